//! The real-time algorithm for translucent media (semi-transparent 3D textures), its CPU
//! specification: the shell as cells, three tetrahedra per prism
//! ([`mesobake_bake::surface::shell::Prism::tetrahedra`]), each mapped to texture space by one affine
//! map; per ray, the cells it crosses in order, each integrated on its own and composited
//! front to back.
//!
//! 1. **Cells.** A tetrahedron's affine map takes its four object-space corners to their
//!    texture coordinates (voxel units): the paper's M^{o→t}. Inside a cell the texture is
//!    that affine map, not the prism's exact mapping; the error shrinks as the base mesh is
//!    refined. The shading normal is the texture normal mapped by Mᵀ (the inverse transpose
//!    of the cell's texture → object Jacobian).
//! 2. **Order.** Per ray, every cell it crosses (a BVH over the cells' boxes; entry and exit by
//!    the cell's four planes), sorted by entry: a per-pixel sorted list, which has no cycles
//!    to break (the paper sorts the cells per view instead, SXMPVO). Two cells that share a
//!    face compute its plane from the same three corners in the same order, so a ray crosses
//!    from one into the other without a gap or overlap; a ray lying in a shared face belongs
//!    to exactly one of the two cells (the one whose outward normal's first non-zero
//!    component is negative).
//! 3. **Integration** ([`CellIntegration`]): the paper's fixed number n of samples per cell,
//!    at the midpoints of n equal parts of the stretch, each the voxel it falls in (nearest,
//!    the medium's piecewise-constant definition) with the opacity correction
//!    α = 1 − (1 − α_t)^ℓ, ℓ the part's texture-space length in voxels; or every voxel the
//!    stretch crosses, in closed form (as the ground truth does along its chords).
//! 4. **Filtering** (where the settings ask for it): each crossing reads the level of the
//!    opacity-aware mip-map ([`Medium::coarser`]) nearest to log₂ of its pixel's footprint
//!    in voxels, plus a bias.
//! 5. **Light.** Each sample is shaded with the scene's lights; with shadows, each light's
//!    visibility is looked up in its shadow map ([`ShadowMethod::DeepMap`](crate::medium_settings::ShadowMethod),
//!    [`ShadowMethod::DepthMap`](crate::medium_settings::ShadowMethod): [`super::medium_shadow_map`], built once per renderer) or
//!    is the transmittance of a ray through the cells towards it, integrated the same way
//!    ([`ShadowMethod::Rays`](crate::medium_settings::ShadowMethod), and lights without a map).

use super::accel::BoxBvh;
use super::cell_order::{
    BoundaryFragment, ViewOrder, ViewSort, face_neighbours, far_first, gap_constraints,
};
use super::explicit::intersect;
use super::lighting::shade_transmitted;
use super::medium_shadow_map::{MapMedium, OPAQUE_EXTINCTION, ShadowMap, build_maps};
use super::medium_truth::{DEFAULT_LIGHT_STEP, Gathered, SHADOW_START, integrate_voxel};
use crate::medium_settings::{CellIntegration, TransparencySettings};
use crate::shot::Shot;
use glam::{DAffine3, DMat3, DVec3};
use mesobake_bake::mesostructure::medium::Medium;
use mesobake_bake::surface::shell::{PrismPoint, Shell};
use mesobake_core::camera::Camera;
use mesobake_core::effect::Effect;
use rayon::prelude::*;
use std::borrow::Cow;
use std::ops::ControlFlow;
use std::sync::OnceLock;

/// One tetrahedron of the shell.
#[derive(Clone, Debug)]
pub struct Cell {
    /// Object-space corners.
    pub corners: [DVec3; 4],
    /// Face planes as (outward normal, offset): inside where n·x < offset; face f leaves
    /// out corner f.
    pub planes: [(DVec3, f64); 4],
    /// Object → texture (voxel units): the paper's M^{o→t}.
    pub to_texture: DAffine3,
    /// Texture normals → object normals (unnormalized): the linear part of M^{o→t},
    /// transposed.
    pub normal_to_object: DMat3,
}

/// A ray's stretch through one cell.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Crossing {
    /// Ray parameter where it enters the cell.
    pub t_in: f64,
    /// Ray parameter where it leaves.
    pub t_out: f64,
    /// The cell's index.
    pub cell: usize,
}

/// The shell's tetrahedra, ready for crossing.
pub struct CellMesh {
    cells: Vec<Cell>,
    /// Per cell, the cell across each face.
    neighbours: Vec<[Option<u32>; 4]>,
    bvh: BoxBvh,
}

impl CellMesh {
    /// The three tetrahedra of every prism of `shell`, textured for a grid of `scale`
    /// voxels per texture unit; cells without volume are left out.
    pub fn new(shell: &Shell, scale: DVec3) -> CellMesh {
        let mut cells = Vec::with_capacity(shell.prisms.len() * 3);
        for prism in &shell.prisms {
            let corner = |(i, top): (usize, bool)| {
                let mut bary = [0.0; 3];
                bary[i] = 1.0;
                let q = PrismPoint {
                    bary,
                    w: f64::from(u8::from(top)),
                };
                (prism.point(q), prism.texture(q) * scale)
            };
            for tet in prism.tetrahedra() {
                let corners = tet.map(corner);
                let (p, t) = (corners.map(|c| c.0), corners.map(|c| c.1));
                cells.extend(Cell::new(p, t));
            }
        }
        CellMesh::from_cells(cells)
    }

    /// The mesh of `cells`: their neighbours across shared faces and their BVH.
    fn from_cells(cells: Vec<Cell>) -> CellMesh {
        CellMesh {
            neighbours: face_neighbours(&cells.iter().map(|c| c.corners).collect::<Vec<_>>()),
            bvh: BoxBvh::new(cells.iter().map(Cell::bounds).collect()),
            cells,
        }
    }

    /// Number of cells.
    pub fn len(&self) -> usize {
        self.cells.len()
    }

    /// Whether there are no cells.
    pub fn is_empty(&self) -> bool {
        self.cells.is_empty()
    }

    /// The cells, in the order their indices ([`Crossing::cell`]) name them.
    pub fn cells(&self) -> &[Cell] {
        &self.cells
    }

    /// A drawing order of the cells for `camera`, back to front, by `sort`
    /// ([`super::cell_order`]): across every shared face the far cell first; with SXMPVO
    /// also across every gap a pixel's ray crosses between boundary faces; otherwise the
    /// farthest centroid first.
    pub fn view_order(&self, camera: &Camera, sort: ViewSort) -> ViewOrder {
        let eye = DVec3::from(camera.eye);
        let distance: Vec<f64> = self
            .cells
            .iter()
            .map(|c| (c.corners.iter().sum::<DVec3>() / 4.0).distance_squared(eye))
            .collect();
        let mut behind = match sort {
            ViewSort::Sxmpvo => gap_constraints(self.boundary_fragments(camera)),
            ViewSort::Mpvonc => Vec::new(),
        };
        for (c, (cell, across)) in self.cells.iter().zip(&self.neighbours).enumerate() {
            for (&(n, d), neighbour) in cell.planes.iter().zip(across) {
                if let Some(neighbour) = *neighbour
                    && n.dot(eye) > d
                {
                    behind.push((c as u32, neighbour));
                }
            }
        }
        far_first(&distance, &behind)
    }

    /// Every crossing of a pixel centre's ray with a boundary face (a face of one cell only):
    /// each face is cast through the pixels its projection's bounding box covers (every
    /// pixel, where a corner lies behind the eye's plane).
    fn boundary_fragments(&self, camera: &Camera) -> Vec<BoundaryFragment> {
        let plane = camera.image_plane();
        let (width, height) = (camera.width, camera.height);
        let faces: Vec<(usize, usize)> = (self.neighbours.iter().enumerate())
            .flat_map(|(c, n)| (0..4).filter(|&f| n[f].is_none()).map(move |f| (c, f)))
            .collect();
        faces
            .par_iter()
            .flat_map_iter(|&(c, f)| {
                let cell = &self.cells[c];
                let mut corners = [DVec3::ZERO; 3];
                for (slot, i) in corners.iter_mut().zip((0..4).filter(|&i| i != f)) {
                    *slot = cell.corners[i];
                }
                // Pixel centres lie at half-integers; one pixel's margin for rounding.
                let span = |lo: f64, hi: f64, n: u32| {
                    let first = (lo - 1.5).ceil().max(0.0);
                    let last = (hi + 0.5).floor().min(f64::from(n) - 1.0);
                    first as u32..=last as u32
                };
                let (xs, ys) = match corners.map(|p| plane.project(p)) {
                    [Some(a), Some(b), Some(c)] => (
                        span(a[0].min(b[0]).min(c[0]), a[0].max(b[0]).max(c[0]), width),
                        span(a[1].min(b[1]).min(c[1]), a[1].max(b[1]).max(c[1]), height),
                    ),
                    _ => (0..=width - 1, 0..=height - 1),
                };
                let outward = cell.planes[f].0;
                ys.flat_map(move |y| xs.clone().map(move |x| (x, y)))
                    .filter_map(move |(x, y)| {
                        let dir = plane.pixel_direction(x, y);
                        let (t, bary) = intersect(&corners, plane.eye, dir)?;
                        (t > 0.0 && bary.iter().all(|&b| b >= 0.0)).then(|| BoundaryFragment {
                            pixel: y * width + x,
                            t,
                            cell: c as u32,
                            leaving: outward.dot(dir) > 0.0,
                        })
                    })
            })
            .collect()
    }

    /// The pixels of `camera`'s image where compositing the cells in `order` (back to front)
    /// differs from the per-pixel sorted list: some two cells the pixel centre's ray crosses
    /// come in the wrong order.
    pub fn misordered_pixels(&self, camera: &Camera, order: &[u32]) -> usize {
        let mut position = vec![0usize; self.cells.len()];
        for (i, &c) in order.iter().enumerate() {
            position[c as usize] = i;
        }
        (0..camera.height)
            .into_par_iter()
            .map(|y| {
                (0..camera.width)
                    .filter(|&x| {
                        let (origin, dir) = camera.ray(x, y);
                        // Cells the ray only touches (at an edge or corner) add nothing.
                        let crossings: Vec<Crossing> =
                            (self.crossings(origin, dir, 0.0, f64::INFINITY).into_iter())
                                .filter(|c| c.t_out > c.t_in)
                                .collect();
                        // Along the ray each cell must be drawn after the next one.
                        crossings
                            .windows(2)
                            .any(|w| position[w[0].cell] < position[w[1].cell])
                    })
                    .count()
            })
            .sum()
    }

    /// Each cell's bounding box (lower and upper corners).
    pub fn bounds(&self) -> Vec<(DVec3, DVec3)> {
        self.cells.iter().map(Cell::bounds).collect()
    }

    /// Every cell that `origin + t·dir`, t ∈ [`t_min`, `t_max`], crosses, clipped to that
    /// range and sorted by entry.
    pub fn crossings(&self, origin: DVec3, dir: DVec3, t_min: f64, t_max: f64) -> Vec<Crossing> {
        let mut out = Vec::new();
        self.bvh.candidates(origin, dir, t_min, t_max, |cell, _| {
            if let Some((t_in, t_out)) = self.cells[cell].clip(origin, dir, t_min, t_max) {
                out.push(Crossing { t_in, t_out, cell });
            }
        });
        out.sort_by(|a, b| a.t_in.total_cmp(&b.t_in).then(a.cell.cmp(&b.cell)));
        out
    }
}

impl Cell {
    /// The cell with object corners `p` and texture corners `t`, or `None` without volume.
    fn new(p: [DVec3; 4], t: [DVec3; 4]) -> Option<Cell> {
        let object = DMat3::from_cols(p[1] - p[0], p[2] - p[0], p[3] - p[0]);
        let det = object.determinant();
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let texture = DMat3::from_cols(t[1] - t[0], t[2] - t[0], t[3] - t[0]);
        let linear = texture * object.inverse();
        let to_texture = DAffine3 {
            matrix3: linear,
            translation: t[0] - linear * p[0],
        };
        // Face f leaves out corner f; its plane is computed from its corners in a canonical
        // order, so that the neighbour sharing the face computes the same plane exactly.
        let planes = [0, 1, 2, 3].map(|f| {
            let mut face: Vec<DVec3> = (0..4).filter(|&c| c != f).map(|c| p[c]).collect();
            face.sort_by(|a, b| {
                a.x.total_cmp(&b.x)
                    .then(a.y.total_cmp(&b.y))
                    .then(a.z.total_cmp(&b.z))
            });
            let n = (face[1] - face[0]).cross(face[2] - face[0]);
            let d = n.dot(face[0]);
            if n.dot(p[f]) > d { (-n, -d) } else { (n, d) }
        });
        Some(Cell {
            corners: p,
            planes,
            to_texture,
            normal_to_object: linear.transpose(),
        })
    }

    /// The cell's bounding box.
    fn bounds(&self) -> (DVec3, DVec3) {
        let lo = self
            .corners
            .into_iter()
            .reduce(DVec3::min)
            .expect("four corners");
        let hi = self
            .corners
            .into_iter()
            .reduce(DVec3::max)
            .expect("four corners");
        (lo, hi)
    }

    /// The stretch of `origin + t·dir`, t ∈ [`t_min`, `t_max`], inside the cell, if it has
    /// length.
    fn clip(&self, origin: DVec3, dir: DVec3, t_min: f64, t_max: f64) -> Option<(f64, f64)> {
        let (mut lo, mut hi) = (t_min, t_max);
        for &(n, d) in &self.planes {
            let along = n.dot(dir);
            let inside = d - n.dot(origin);
            if along == 0.0 {
                // Parallel: inside the half-space, or in the face that this cell owns.
                if inside < 0.0 || (inside == 0.0 && !owns(n)) {
                    return None;
                }
            } else if along > 0.0 {
                hi = hi.min(inside / along);
            } else {
                lo = lo.max(inside / along);
            }
        }
        (lo < hi).then_some((lo, hi))
    }
}

/// Whether a cell owns the face with outward normal `n`, when a ray lies in it: the first
/// non-zero component of `n` is negative (its neighbour's, `−n`, is then positive).
fn owns(n: DVec3) -> bool {
    n.to_array()
        .into_iter()
        .find(|&c| c != 0.0)
        .is_some_and(|c| c < 0.0)
}

/// The real-time algorithm's CPU specification over one shell and one medium.
pub struct CellRenderer<'a> {
    cells: CellMesh,
    medium: &'a Medium,
    /// The mip-map's coarser levels (level l at l − 1), where the settings ask for it.
    coarser: Cow<'a, [Medium]>,
    settings: TransparencySettings,
    /// The lights' shadow maps, built on first use.
    shadow_maps: OnceLock<Vec<Option<ShadowMap>>>,
}

impl<'a> CellRenderer<'a> {
    /// Splits `shell` into cells for `medium`, integrated as `settings` says (building the
    /// mip-map if they ask for it).
    pub fn new(shell: &Shell, medium: &'a Medium, settings: TransparencySettings) -> Self {
        let coarser = match settings.mipmap {
            true => medium.coarser_levels(),
            false => Vec::new(),
        };
        Self::build(shell, medium, Cow::Owned(coarser), settings)
    }

    /// [`CellRenderer::new`] over a medium's mip chain already built (a medium package's
    /// levels, level 0 first); the coarser levels are read only where `settings` ask for
    /// the mip-map.
    pub fn with_levels(
        shell: &Shell,
        levels: &'a [Medium],
        settings: TransparencySettings,
    ) -> Self {
        let coarser = if settings.mipmap { &levels[1..] } else { &[] };
        Self::build(shell, &levels[0], Cow::Borrowed(coarser), settings)
    }

    fn build(
        shell: &Shell,
        medium: &'a Medium,
        coarser: Cow<'a, [Medium]>,
        settings: TransparencySettings,
    ) -> Self {
        let d = medium.dims();
        let scale = DVec3::new(f64::from(d.x), f64::from(d.y), f64::from(d.z));
        CellRenderer {
            cells: CellMesh::new(shell, scale),
            medium,
            coarser,
            settings,
            shadow_maps: OnceLock::new(),
        }
    }

    /// The shadow maps of `shot`'s lights, per light (`None` where a light has none), built
    /// on the first call: a renderer serves one shot's lights.
    pub fn shadow_maps(&self, shot: &Shot) -> &[Option<ShadowMap>] {
        self.shadow_maps.get_or_init(|| build_maps(self, shot))
    }

    /// The cells.
    pub fn cells(&self) -> &CellMesh {
        &self.cells
    }

    /// The medium and, where the settings ask for the mip-map, its coarser levels.
    pub fn levels(&self) -> impl Iterator<Item = &Medium> {
        std::iter::once(self.medium).chain(self.coarser.iter())
    }

    /// Mip-map level `level` of the medium (0: the medium itself).
    fn level(&self, level: usize) -> &Medium {
        level
            .checked_sub(1)
            .map_or(self.medium, |l| &self.coarser[l])
    }

    /// The mip level for the crossing `c` of a camera ray whose pixels subtend
    /// `pixel_angle` radians: log₂ of the pixel's footprint at the entry, in voxels (the
    /// object footprint times the cell's mean voxels per object length, ∛|det M|), plus the
    /// bias, rounded to the nearest level that exists.
    fn level_for(&self, c: &Crossing, pixel_angle: f64) -> usize {
        if self.coarser.is_empty() {
            return 0;
        }
        let density = self.cells.cells[c.cell]
            .to_texture
            .matrix3
            .determinant()
            .abs()
            .cbrt();
        let lambda = (c.t_in.max(0.0) * pixel_angle * density).log2() + self.settings.mip_bias;
        if lambda.is_finite() {
            lambda.round().clamp(0.0, self.coarser.len() as f64) as usize
        } else {
            0
        }
    }

    /// The crossing `c` of `origin + t·dir` in the texture of mip level `level`: its ends
    /// and length (in that level's voxels).
    fn segment(
        &self,
        origin: DVec3,
        dir: DVec3,
        c: &Crossing,
        level: usize,
    ) -> (DVec3, DVec3, f64) {
        let cell = &self.cells.cells[c.cell];
        let texel = 0.5f64.powi(level as i32);
        let a = cell.to_texture.transform_point3(origin + dir * c.t_in) * texel;
        let b = cell.to_texture.transform_point3(origin + dir * c.t_out) * texel;
        (a, b, (b - a).length())
    }

    /// The settings' samples along the texture segment from `a` to `b` (of non-zero length):
    /// the midpoints of equal parts, as (distance from `a`, texture point).
    fn sample_points(&self, a: DVec3, b: DVec3) -> impl Iterator<Item = (f64, DVec3)> {
        let n = self.settings.samples;
        let len = (b - a).length();
        let part = len / f64::from(n);
        (0..n).map(move |i| {
            let s = (f64::from(i) + 0.5) * part;
            (s, a + (b - a) * (s / len))
        })
    }

    /// Integrates the crossing `c` of `origin + t·dir` in mip level `level`: `light(t,
    /// texture point, voxel)` gives the light scattered at each sample or piece (texture
    /// points and voxels of that level).
    fn integrate(
        &self,
        origin: DVec3,
        dir: DVec3,
        c: &Crossing,
        level: usize,
        out: &mut Gathered,
        mut light: impl FnMut(f64, DVec3, usize) -> DVec3,
    ) -> ControlFlow<()> {
        let medium = self.level(level);
        let (a, b, len) = self.segment(origin, dir, c, level);
        if len == 0.0 {
            return ControlFlow::Continue(());
        }
        // Ray parameter per texture-space length.
        let dt = (c.t_out - c.t_in) / len;
        match self.settings.integration {
            CellIntegration::Samples => {
                let part = len / f64::from(self.settings.samples);
                for (s, texture) in self.sample_points(a, b) {
                    let Some(v) = medium.voxel_at(texture) else {
                        continue;
                    };
                    let absorbed = 1.0 - medium.transmittance(v, part);
                    if absorbed > 0.0 {
                        out.composite(light(c.t_in + s * dt, texture, v), absorbed)?;
                    }
                }
                ControlFlow::Continue(())
            }
            CellIntegration::Exact => {
                let view = (b - a) / len;
                medium.walk(a, view, len, |v, s0, s1| {
                    integrate_voxel(medium, v, (s0, s1), DEFAULT_LIGHT_STEP, out, |u| {
                        light(c.t_in + u * dt, a + view * u, v)
                    })
                })
            }
        }
    }

    /// Transmittance through the cells along `origin + t·dir` (unit `dir`), t ∈ [`t_min`,
    /// `t_max`], integrated like the camera rays.
    pub fn transmittance(&self, origin: DVec3, dir: DVec3, t_min: f64, t_max: f64) -> f64 {
        self.transmittance_in(0, origin, dir, t_min, t_max)
    }

    /// [`CellRenderer::transmittance`] in mip level `level`.
    fn transmittance_in(&self, level: usize, o: DVec3, d: DVec3, t_min: f64, t_max: f64) -> f64 {
        let mut out = Gathered::EMPTY;
        for c in self.cells.crossings(o, d, t_min, t_max) {
            if self
                .integrate(o, d, &c, level, &mut out, |_, _, _| DVec3::ZERO)
                .is_break()
            {
                break;
            }
        }
        out.transmittance
    }

    /// What the camera ray `origin + t·dir` (unit `dir`), t ≥ 0, gathers under the scene's
    /// lights (shadows when the scene asks for them). With the mip-map, each crossing and its
    /// shadow rays read the level its pixel's footprint calls for.
    pub fn gather(&self, shot: &Shot, origin: DVec3, dir: DVec3) -> Gathered {
        let shadows = shot.wants(Effect::Shadows);
        let maps = if shadows { self.shadow_maps(shot) } else { &[] };
        let camera = &shot.camera;
        let pixel_angle =
            2.0 * (camera.fov_y_degrees.to_radians() / 2.0).tan() / f64::from(camera.height);
        let mut out = Gathered::EMPTY;
        for c in self.cells.crossings(origin, dir, 0.0, f64::INFINITY) {
            let cell = &self.cells.cells[c.cell];
            let to_object = cell.normal_to_object;
            let level = self.level_for(&c, pixel_angle);
            let medium = self.level(level);
            let flow = self.integrate(origin, dir, &c, level, &mut out, |t, texture, v| {
                let point = origin + dir * t;
                let normal = medium
                    .material()
                    .normal_at(texture)
                    .and_then(|n| (to_object * n).try_normalize());
                shade_transmitted(
                    &shot.lights,
                    &shot.material,
                    point,
                    normal,
                    medium.colour(v),
                    -dir,
                    |light, inc| {
                        if !shadows {
                            return 1.0;
                        }
                        // The object distance that is SHADOW_START voxels towards the light.
                        let along = cell.to_texture.matrix3 * inc.direction;
                        let start = SHADOW_START / along.length();
                        if start >= inc.distance {
                            return 1.0;
                        }
                        if let Some(Some(map)) = maps.get(light) {
                            return map.visibility(point, start);
                        }
                        self.transmittance_in(level, point, inc.direction, start, inc.distance)
                    },
                )
            });
            if flow.is_break() {
                break;
            }
        }
        out
    }

    /// The camera ray's composited radiance, or `None` where it met no medium.
    pub fn radiance(&self, shot: &Shot, origin: DVec3, dir: DVec3) -> Option<DVec3> {
        let g = self.gather(shot, origin, dir);
        (g.transmittance < 1.0).then_some(g.radiance)
    }
}

impl MapMedium for CellRenderer<'_> {
    /// The settings it integrates by.
    fn settings(&self) -> TransparencySettings {
        self.settings
    }

    fn bounds(&self) -> Vec<(DVec3, DVec3)> {
        self.cells.bounds()
    }

    /// Visits the optical depth along `origin + t·dir` (unit `dir`), t ∈ [`t_min`, `t_max`],
    /// through the cells in mip level 0, in order: `f(t_a, t_b, τ)` per piece of constant
    /// medium (a voxel's stretch, or a sample's share of its crossing), τ = σ·ℓ with
    /// σ = −ln(1 − α) per voxel length ([`OPAQUE_EXTINCTION`] for α = 1). Stops when `f`
    /// breaks.
    fn optical_depths(
        &self,
        origin: DVec3,
        dir: DVec3,
        t_min: f64,
        t_max: f64,
        mut f: impl FnMut(f64, f64, f64) -> ControlFlow<()>,
    ) -> ControlFlow<()> {
        let medium = self.medium;
        let extinction = |v: usize| {
            let alpha = medium.opacity(v);
            if alpha >= 1.0 {
                OPAQUE_EXTINCTION
            } else {
                -(1.0 - alpha).ln()
            }
        };
        for c in self.cells.crossings(origin, dir, t_min, t_max) {
            let (a, b, len) = self.segment(origin, dir, &c, 0);
            if len == 0.0 {
                continue;
            }
            let dt = (c.t_out - c.t_in) / len;
            let t = |s: f64| c.t_in + s * dt;
            match self.settings.integration {
                CellIntegration::Samples => {
                    let part = len / f64::from(self.settings.samples);
                    for (s, texture) in self.sample_points(a, b) {
                        if let Some(v) = medium.voxel_at(texture) {
                            let (s0, s1) = (s - 0.5 * part, s + 0.5 * part);
                            f(t(s0), t(s1), extinction(v) * part)?;
                        }
                    }
                }
                CellIntegration::Exact => {
                    medium.walk(a, (b - a) / len, len, |v, s0, s1| {
                        f(t(s0), t(s1), extinction(v) * (s1 - s0))
                    })?;
                }
            }
        }
        ControlFlow::Continue(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tetrahedron with a base triangle of circumradius `r` about the z axis at depth
    /// `z` and its apex at `apex`, the texture its object space.
    fn cone(z: f64, r: f64, apex: DVec3) -> Cell {
        let s = 3f64.sqrt() / 2.0;
        let p = [
            DVec3::new(r, 0.0, z),
            DVec3::new(-r / 2.0, r * s, z),
            DVec3::new(-r / 2.0, -r * s, z),
            apex,
        ];
        Cell::new(p, p).unwrap()
    }

    /// Two cells that share no face, seen down −z from the origin: `near` (centroid 5.0
    /// away) hides the middle of `far`, whose base lies at depth 6 but whose apex reaches
    /// back towards the eye off to the side (centroid 4.7 away). MPVONC draws the farther
    /// centroid first, `near`, and gets the pixels where both lie wrong; SXMPVO relates them
    /// across the gap between `near`'s back and `far`'s front and gets every pixel right.
    #[test]
    fn sxmpvo_orders_cells_that_share_no_face() {
        let near = cone(-5.1, 0.2, DVec3::new(0.0, 0.0, -4.9));
        let far = cone(-6.0, 0.3, DVec3::new(3.0, 0.0, -0.5));
        let mesh = CellMesh::from_cells(vec![near, far]);
        let camera = Camera {
            eye: [0.0; 3],
            target: [0.0, 0.0, -1.0],
            up: [0.0, 1.0, 0.0],
            fov_y_degrees: 8.0,
            width: 33,
            height: 33,
            samples_per_pixel: Default::default(),
            subpixel: [0.5, 0.5],
        };
        let sx = mesh.view_order(&camera, ViewSort::Sxmpvo);
        assert_eq!(
            (sx.order.as_slice(), sx.cycles_broken),
            ([1, 0].as_slice(), 0)
        );
        assert_eq!(mesh.misordered_pixels(&camera, &sx.order), 0);
        let mpvonc = mesh.view_order(&camera, ViewSort::Mpvonc);
        assert_eq!(mpvonc.order, [0, 1]);
        // Wherever the two overlap on screen (measured: 110 pixels).
        let wrong = mesh.misordered_pixels(&camera, &mpvonc.order);
        assert!(wrong >= 50, "{wrong} pixels");
    }

    fn unit_cell() -> Cell {
        let p = [DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z];
        Cell::new(p, p.map(|c| c * 2.0)).unwrap()
    }

    /// Entry and exit of the unit corner tetrahedron x, y, z ≥ 0, x + y + z ≤ 1 along the
    /// diagonal: t from 0 to 1/√3 · √3 = 1/3 per unit of (1, 1, 1).
    #[test]
    fn clipping_finds_entry_and_exit_by_the_planes() {
        let c = unit_cell();
        let (a, b) = c.clip(DVec3::splat(-1.0), DVec3::ONE, -10.0, 10.0).unwrap();
        assert!(
            (a - 1.0).abs() < 1e-12 && (b - 4.0 / 3.0).abs() < 1e-12,
            "{a} {b}"
        );
        assert!(
            c.clip(DVec3::new(2.0, 2.0, -1.0), DVec3::Z, -10.0, 10.0)
                .is_none()
        );
        let t = c.to_texture.transform_point3(DVec3::new(0.25, 0.25, 0.25));
        assert!((t - DVec3::splat(0.5)).length() < 1e-12);
    }

    /// A ray lying in a face shared by two cells belongs to exactly one of them.
    #[test]
    fn a_ray_in_a_shared_face_belongs_to_one_cell() {
        let below = unit_cell();
        // The mirror image across the face z = 0.
        let p = [DVec3::ZERO, DVec3::X, DVec3::Y, -DVec3::Z];
        let above = Cell::new(p, p).unwrap();
        let origin = DVec3::new(-1.0, 0.2, 0.0);
        let hits = [&below, &above]
            .iter()
            .filter(|c| c.clip(origin, DVec3::X, -10.0, 10.0).is_some())
            .count();
        assert_eq!(hits, 1);
    }
}
