//! Built-in translucent media ([`crate::mesostructure::medium`]), after the colour plates of
//! the semi-transparent 3D textures paper: `fur` (translucent strands on an opaque skin),
//! `clouds` (puffs over an opaque ground), `inclusions` (opaque ellipsoids in a tinted
//! medium) and `absorbing` (a uniform green medium).
//!
//! Each is defined on the unit tile, periodic in x and y, over the height Z/X of the grid,
//! and sampled at voxel centres; the volumes carry the opacity channel, their colour as
//! albedo, and the opaque voxels (α = 1) as their solid (density = opacity, threshold 1).

use crate::mesostructure::volume::Volume;
use mesobake_core::error::Result;
use mesobake_core::limits::Limits;
use mesobake_package::grid::Dims;
use std::f64::consts::TAU;

/// The built-in translucent media.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum MediumKind {
    /// Slanted translucent strands of varying length on an opaque skin.
    Fur,
    /// Soft cloud puffs in the upper half over an opaque ground.
    Clouds,
    /// Opaque ellipsoids trapped in a faintly red medium.
    Inclusions,
    /// A uniform absorbing green medium (α = 0.08 per voxel) filling the volume.
    Absorbing,
}

impl MediumKind {
    /// Every medium, in documentation order.
    pub const ALL: [MediumKind; 4] = [
        MediumKind::Fur,
        MediumKind::Clouds,
        MediumKind::Inclusions,
        MediumKind::Absorbing,
    ];

    /// The medium's lower-case name.
    pub fn name(&self) -> &'static str {
        match self {
            MediumKind::Fur => "fur",
            MediumKind::Clouds => "clouds",
            MediumKind::Inclusions => "inclusions",
            MediumKind::Absorbing => "absorbing",
        }
    }
}

/// Opacity per voxel length of the uniform `absorbing` medium.
pub const ABSORBING_OPACITY: f32 = 0.08;

/// A deterministic pseudo-random number in [0, 1) for `(seed, n)` (SplitMix64).
fn random(seed: u64, n: u64) -> f64 {
    let mut z = seed
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add(n.wrapping_mul(0xBF58_476D_1CE4_E5B9));
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 53) as f64
}

/// The shortest offset from `a` to `b` on the unit circle (periodic coordinate).
fn wrapped(b: f64, a: f64) -> f64 {
    let d = b - a;
    d - d.round()
}

/// Opacity and linear-ish display colour (0..1 per channel) at design point `p` (x, y in the
/// unit tile, z in [0, height]).
fn sample(kind: MediumKind, p: [f64; 3], height: f64, voxel: f64) -> (f64, [f64; 3]) {
    let [x, y, z] = p;
    match kind {
        MediumKind::Absorbing => (f64::from(ABSORBING_OPACITY), [0.25, 0.8, 0.35]),
        MediumKind::Fur => {
            if z < 2.0 * voxel {
                return (1.0, [0.35, 0.22, 0.12]);
            }
            const STRANDS: u64 = 56;
            let mut best: Option<(f64, [f64; 3])> = None;
            for s in 0..STRANDS {
                let (bx, by) = (random(1, 3 * s), random(1, 3 * s + 1));
                let length = height * (0.55 + 0.45 * random(1, 3 * s + 2));
                if z > length {
                    continue;
                }
                let angle = TAU * random(2, s);
                let lean = 0.35 * z / height;
                let f = z / length;
                let (cx, cy) = (bx + lean * angle.cos() * f, by + lean * angle.sin() * f);
                let r = (1.6 - 0.9 * f) * voxel;
                let d2 = wrapped(x, cx).powi(2) + wrapped(y, cy).powi(2);
                if d2 < r * r {
                    let alpha = 0.75 * (1.0 - d2 / (r * r)).sqrt();
                    let tip = 0.5 + 0.5 * f;
                    let colour = [0.55 * tip + 0.2, 0.38 * tip + 0.1, 0.2 * tip + 0.05];
                    if best.is_none_or(|b| b.0 < alpha) {
                        best = Some((alpha, colour));
                    }
                }
            }
            best.unwrap_or((0.0, [0.0; 3]))
        }
        MediumKind::Clouds => {
            if z < 2.0 * voxel {
                let land = 0.5 + 0.5 * (TAU * x).sin() * (TAU * y).cos();
                return (
                    1.0,
                    [0.15 + 0.2 * land, 0.3 + 0.2 * land, 0.45 - 0.25 * land],
                );
            }
            let mut density = 0.0;
            for c in 0..6u64 {
                let centre = [
                    random(3, 3 * c),
                    random(3, 3 * c + 1),
                    height * (0.55 + 0.25 * random(3, 3 * c + 2)),
                ];
                let d2 = wrapped(x, centre[0]).powi(2)
                    + wrapped(y, centre[1]).powi(2)
                    + ((z - centre[2]) / (0.5 * height)).powi(2) * 0.04;
                density += (-d2 / 0.012).exp();
            }
            ((0.35 * density).min(1.0), [0.95, 0.95, 0.97])
        }
        MediumKind::Inclusions => {
            for e in 0..3u64 {
                let c = [
                    random(4, 4 * e),
                    random(4, 4 * e + 1),
                    height * (0.3 + 0.4 * random(4, 4 * e + 2)),
                ];
                let radii = [0.16, 0.1, 0.22 * height];
                let turn = TAU * random(4, 4 * e + 3);
                let (dx, dy) = (wrapped(x, c[0]), wrapped(y, c[1]));
                let (u, v) = (
                    dx * turn.cos() + dy * turn.sin(),
                    -dx * turn.sin() + dy * turn.cos(),
                );
                let w = z - c[2];
                if (u / radii[0]).powi(2) + (v / radii[1]).powi(2) + (w / radii[2]).powi(2) <= 1.0 {
                    return (1.0, [0.85, 0.75, 0.3]);
                }
            }
            (0.04, [0.85, 0.15, 0.12])
        }
    }
}

/// The medium as a volume on `dims` (X = Y: the samples are square tiles).
pub fn volume(kind: MediumKind, dims: Dims, limits: &Limits) -> Result<Volume> {
    let height = crate::mesostructure::samples::tile_height(dims)?;
    limits.check("medium volume", dims.voxel_count(), 11)?;
    let voxel = 1.0 / f64::from(dims.x);
    let n = dims.voxel_count() as usize;
    let (mut opacity, mut albedo) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for k in 0..dims.z {
        for j in 0..dims.y {
            for i in 0..dims.x {
                let p = [i, j, k].map(|c| (f64::from(c) + 0.5) * voxel);
                let (alpha, colour) = sample(kind, p, height, voxel);
                opacity.push(alpha as f32);
                albedo.push(colour.map(|c| (c * 255.0).round().clamp(0.0, 255.0) as u8));
            }
        }
    }
    Volume::new(dims, opacity.clone(), 1.0, Some(albedo))?.with_opacity(opacity)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each medium is what its documentation says: translucent voxels, and opaque ones only
    /// where it has an opaque part.
    #[test]
    fn media_have_their_documented_opacities() {
        let dims = Dims::new(32, 32, 16).unwrap();
        for kind in MediumKind::ALL {
            let v = volume(kind, dims, &Limits::default()).unwrap();
            let a = v.opacity().unwrap();
            let translucent = a.iter().filter(|&&x| x > 0.0 && x < 1.0).count();
            let opaque = a.iter().filter(|&&x| x == 1.0).count();
            assert!(translucent > 0, "{kind:?} has no translucent voxel");
            match kind {
                MediumKind::Absorbing => {
                    assert!(a.iter().all(|&x| x == ABSORBING_OPACITY));
                }
                MediumKind::Fur | MediumKind::Clouds => {
                    // The opaque skin or ground: the two lowest layers of 16.
                    assert_eq!(opaque, 2 * 32 * 32, "{kind:?}");
                }
                MediumKind::Inclusions => assert!(opaque > 0),
            }
            assert_eq!(v.occupancy().solid_count() as usize, opaque, "{kind:?}");
        }
    }
}
