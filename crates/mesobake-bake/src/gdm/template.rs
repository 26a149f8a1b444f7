//! Exact GDM bake of voxel volumes with ray templates, 64 samples per machine word.
//!
//! Every sample sits at a voxel centre, so for one direction the ray from sample (i, j, k) is
//! the ray from (½, ½, ½) translated by the integer vector (i, j, k): it visits the same
//! sequence of voxel offsets at the same distances (template-based ray casting, Yagel &
//! Kaufman 1992). One exact DDA per direction builds that *template* — the closed-box DDA of
//! [`super::volume_caster`], ties included — and every sample then walks it. The walk is done
//! for a whole x row of samples at once: for a template offset (di, dj, dk) the solid flags
//! of all samples of row (j, k) are the occupancy bits of row (j+dj, k+dk) rotated by di,
//! so one rotate-and-mask tests 64 rays. Results are bit-identical to per-ray traversal.

use crate::mesostructure::volume::Occupancy;
use mesobake_core::error::Result;
use mesobake_core::limits::Limits;
use mesobake_package::grid::{Dims, DirectionGrid};

/// One voxel visited by the template ray.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Step {
    /// x offset modulo X: the rotation of the occupancy row.
    pub(crate) shift: u32,
    /// y offset modulo Y.
    pub(crate) dj: u32,
    /// z offset (layers are not periodic).
    pub(crate) dk: i32,
    /// Distance at which the ray enters (or first touches) the voxel.
    pub(crate) t: f32,
    /// x and y offsets before wrapping around.
    pub(crate) unwrapped: [i32; 2],
}

/// Whether rows of width `x` can be rotated word-wise.
pub fn supports(dims: Dims) -> bool {
    dims.x <= 64 || dims.x.is_multiple_of(64)
}

/// The voxels the ray from (½, ½, ½) along `v` touches, in order, until it has left `z`
/// layers behind in its direction of travel. Voxels first touched at the same distance (the
/// ray crossing an edge or corner) are listed inside the layer before outside it.
fn build_template(dims: Dims, v: [f64; 3]) -> Vec<Step> {
    let o = [0.5f64; 3];
    let inv = v.map(|c| 1.0 / c);
    let sign = v.map(|c| if c > 0.0 { 1i64 } else { -1 });
    let mut cell = [0i64; 3];
    let plane = |cell: i64, a: usize| (cell + (sign[a] + 1) / 2) as f64;
    let mut t_next: [f64; 3] = std::array::from_fn(|a| {
        if v[a] == 0.0 {
            f64::INFINITY
        } else {
            (plane(0, a) - o[a]) * inv[a]
        }
    });
    let mut steps = Vec::new();
    let push = |steps: &mut Vec<Step>, c: [i64; 3], t: f64| {
        steps.push(Step {
            shift: c[0].rem_euclid(dims.x as i64) as u32,
            dj: c[1].rem_euclid(dims.y as i64) as u32,
            dk: c[2] as i32,
            t: t as f32,
            unwrapped: [c[0] as i32, c[1] as i32],
        })
    };
    while cell[2].abs() < dims.z as i64 {
        let t = t_next[0].min(t_next[1]).min(t_next[2]);
        let ties: Vec<usize> = (0..3).filter(|&a| t_next[a] == t).collect();
        let mut next = cell;
        for &a in &ties {
            next[a] += sign[a];
        }
        if ties.len() == 1 {
            push(&mut steps, next, t);
        } else {
            // Every voxel touching the edge or corner, except the one being left; those in
            // the current layer first, so that leaving the volume is seen last.
            let mut touched = Vec::new();
            for mask in 1..(1u32 << ties.len()) {
                let mut c = cell;
                for (bit, &a) in ties.iter().enumerate() {
                    if mask & (1 << bit) != 0 {
                        c[a] += sign[a];
                    }
                }
                touched.push(c);
            }
            touched.sort_by_key(|c| (c[2] - cell[2]).abs());
            for c in touched {
                push(&mut steps, c, t);
            }
        }
        for &a in &ties {
            t_next[a] = (plane(next[a], a) - o[a]) * inv[a];
        }
        cell = next;
    }
    steps
}

/// The template of one direction, walked one sample at a time.
pub(crate) struct Template {
    steps: Vec<Step>,
    /// Whether the direction points up (+z).
    up: bool,
}

impl Template {
    /// The template of direction `v` on the grid of `dims`.
    pub(crate) fn new(dims: Dims, v: [f64; 3]) -> Self {
        Template {
            steps: build_template(dims, v),
            up: v[2] > 0.0,
        }
    }

    /// The steps a ray from layer `k` takes up to distance `max_t` while it can still meet
    /// solid: it stops on leaving `solid`, the lowest and highest layers holding any (`None`:
    /// the volume is empty), in its direction of travel. Rays left pending escape.
    pub(crate) fn steps_within(&self, solid: Option<(u32, u32)>, k: u32, max_t: f64) -> &[Step] {
        let Some((lo, hi)) = solid else {
            return &[];
        };
        let (k, lo, hi) = (k as i32, lo as i32, hi as i32);
        let beyond = |s: &Step| {
            if self.up {
                k + s.dk > hi
            } else {
                k + s.dk < lo
            }
        };
        let end = self
            .steps
            .iter()
            .position(|s| beyond(s) || s.t as f64 > max_t)
            .unwrap_or(self.steps.len());
        &self.steps[..end]
    }

    /// Walks `steps` for the 64 samples of word `w` of row (j, k) at once: writes 0 for
    /// samples in solid, the distance of the first solid voxel for rays that touch one, and
    /// returns the lanes (bit i = sample 64w + i) still pending.
    pub(crate) fn walk_row(
        &self,
        occ: &Occupancy,
        steps: &[Step],
        j: u32,
        k: u32,
        w: usize,
        out: &mut [f32],
    ) -> u64 {
        let dims = occ.dims();
        let lanes = (dims.x as usize - 64 * w).min(64);
        let mask = if lanes == 64 {
            u64::MAX
        } else {
            (1u64 << lanes) - 1
        };
        let own = occ.row(j, k)[w] & mask;
        let mut inside = own;
        while inside != 0 {
            out[64 * w + inside.trailing_zeros() as usize] = 0.0;
            inside &= inside - 1;
        }
        self.walk_lanes(occ, steps, j, k, w, !own & mask, out)
    }

    /// Walks `steps` for the lanes `pending` of word `w` of row (j, k) (samples outside
    /// solid): writes the distance of the first solid voxel for rays that touch one and
    /// returns the lanes still pending.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn walk_lanes(
        &self,
        occ: &Occupancy,
        steps: &[Step],
        j: u32,
        k: u32,
        w: usize,
        mut pending: u64,
        out: &mut [f32],
    ) -> u64 {
        let dims = occ.dims();
        for s in steps {
            if pending == 0 {
                break;
            }
            let jj = if j + s.dj >= dims.y {
                j + s.dj - dims.y
            } else {
                j + s.dj
            };
            let row = occ.row(jj, (k as i32 + s.dk) as u32);
            let mut hits = rotated_word(row, dims.x, s.shift, w) & pending;
            pending &= !hits;
            while hits != 0 {
                out[64 * w + hits.trailing_zeros() as usize] = s.t;
                hits &= hits - 1;
            }
        }
        pending
    }
}

/// Gathers row bits rotated by `shift`: bit i of the result is bit (i + shift) mod X of `row`.
#[inline(always)]
pub(crate) fn rotated_word(row: &[u64], x: u32, shift: u32, w: usize) -> u64 {
    if x < 64 {
        let mask = (1u64 << x) - 1;
        let r = row[0];
        if shift == 0 {
            r
        } else {
            ((r >> shift) | (r << (x - shift))) & mask
        }
    } else {
        let n = row.len();
        let q = (64 * w + shift as usize) % (x as usize);
        let (qi, qb) = (q / 64, q % 64);
        if qb == 0 {
            row[qi]
        } else {
            (row[qi] >> qb) | (row[(qi + 1) % n] << (64 - qb))
        }
    }
}

/// Refuses direction grids whose longest ray template (one per worker thread) would exceed
/// the memory limit.
pub fn check_memory(dims: Dims, dirs: DirectionGrid, limits: &Limits) -> Result<()> {
    // The most grazing θ bin, from one side of the volume to the other, crosses up to
    // |tan θ|·(|cos φ| + |sin φ|) ≤ √2·|tan θ| voxel walls per layer.
    let grazing = dirs.theta(dirs.n_theta / 2 - 1).tan().abs();
    let longest = (dims.z as f64 * (1.0 + std::f64::consts::SQRT_2 * grazing) + 8.0).ceil();
    let per_template = std::mem::size_of::<Step>() as u64;
    limits.check(
        "a ray template",
        longest as u64,
        per_template * rayon::current_num_threads() as u64,
    )?;
    Ok(())
}

/// Fills one direction's X×Y×Z volume: 0 for samples in solid voxels, the distance to the
/// first solid voxel touched, +∞ for rays that leave the volume first.
pub(crate) fn bake_direction(occ: &Occupancy, v: [f64; 3], volume: &mut [f32]) {
    let dims = occ.dims();
    let template = Template::new(dims, v);
    let solid = occ.solid_layer_range();
    let nx = dims.x as usize;
    for k in 0..dims.z {
        let steps = template.steps_within(solid, k, f64::INFINITY);
        for j in 0..dims.y {
            let out = &mut volume[(k as usize * dims.y as usize + j as usize) * nx..][..nx];
            for w in 0..nx.div_ceil(64) {
                let mut pending = template.walk_row(occ, steps, j, k, w, out);
                while pending != 0 {
                    out[64 * w + pending.trailing_zeros() as usize] = f32::INFINITY;
                    pending &= pending - 1;
                }
            }
        }
    }
}
