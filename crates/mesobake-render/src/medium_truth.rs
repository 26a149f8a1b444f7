//! The ground truth for translucent media ([`mesobake_bake::mesostructure::medium`]): camera rays
//! walk the whole shell with the exact mapping ([`super::shell_walk`]); along each chord the
//! medium's voxels are visited exactly, and the emission–absorption integral is composited
//! front to back in closed form per piece of constant medium:
//!
//! C += T · L · (1 − (1 − α)^ℓ),  T ← T · (1 − α)^ℓ
//!
//! for a piece ℓ voxels long (texture space) of a voxel of opacity α, with L the light the
//! medium scatters there. L is [`shade_transmitted`] with the voxel's colour and the opacity
//! gradient's normal (none where the opacity does not vary), each light weighted by the
//! transmittance of a shadow ray walked the same way through the whole shell to the light.
//! L is evaluated at the start of each piece; pieces are at most `light_step` voxels long
//! (the one approximation, converging as the step shrinks; the transmittance itself is
//! exact). An opaque voxel (α = 1) is all in its first point, where L is the lit surface, so
//! an opaque medium renders as the opaque mesostructure's voxel boxes.
//!
//! Shadow rays start [`SHADOW_START`] voxels towards the light (beyond the chords' own
//! [`CHORD_TOLERANCE`] from the exact path, so that a ray leaving an opaque face does not
//! start inside it). A ray stops once its transmittance falls below [`MIN_TRANSMITTANCE`].
//! The image stores the composited colour over black (premultiplied); a pixel is a hit
//! where the ray met any medium (T < 1).

use super::lighting::shade_transmitted;
use super::shell_walk::{CHORD_TOLERANCE, Chord, ShellWalk};
use crate::shot::Shot;
use glam::{DMat3, DVec3};
use mesobake_bake::mesostructure::medium::Medium;
use mesobake_bake::surface::shell::Shell;
use mesobake_core::effect::Effect;
use std::ops::ControlFlow;

/// Where shadow rays start, in voxels from the shaded point towards the light.
pub const SHADOW_START: f64 = 2.0 * CHORD_TOLERANCE;

/// Transmittance below which a ray counts as fully absorbed.
pub const MIN_TRANSMITTANCE: f64 = 1e-6;

/// The default longest piece, in voxels, over which the scattered light is held constant.
pub const DEFAULT_LIGHT_STEP: f64 = 0.25;

/// What a ray through the medium gathers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gathered {
    /// Composited radiance over black (premultiplied).
    pub radiance: DVec3,
    /// The fraction of the background that shows through.
    pub transmittance: f64,
}

impl Gathered {
    /// Nothing gathered yet: no radiance, everything transmitted.
    pub const EMPTY: Gathered = Gathered {
        radiance: DVec3::ZERO,
        transmittance: 1.0,
    };

    /// Composites, behind what is gathered, a piece of medium that absorbs the fraction
    /// `absorbed` of the light crossing it and scatters `light`; breaks once the ray is
    /// absorbed ([`MIN_TRANSMITTANCE`]).
    pub fn composite(&mut self, light: DVec3, absorbed: f64) -> ControlFlow<()> {
        self.radiance += light * (self.transmittance * absorbed);
        self.transmittance *= 1.0 - absorbed;
        if self.transmittance < MIN_TRANSMITTANCE {
            self.transmittance = 0.0;
            return ControlFlow::Break(());
        }
        ControlFlow::Continue(())
    }
}

/// Composites the stretch [`s0`, `s1`] (voxel lengths) of a segment through voxel `v` of
/// `medium` in closed form: in pieces at most `light_step` long, each absorbing
/// 1 − (1 − α)^ℓ and scattering `light(u)`, the light at the piece's start u.
pub fn integrate_voxel(
    medium: &Medium,
    v: usize,
    (s0, s1): (f64, f64),
    light_step: f64,
    out: &mut Gathered,
    mut light: impl FnMut(f64) -> DVec3,
) -> ControlFlow<()> {
    if medium.opacity(v) <= 0.0 {
        return ControlFlow::Continue(());
    }
    let pieces = ((s1 - s0) / light_step).ceil().max(1.0);
    for p in 0..pieces as u32 {
        let u0 = s0 + (s1 - s0) * f64::from(p) / pieces;
        let u1 = s0 + (s1 - s0) * f64::from(p + 1) / pieces;
        let absorbed = 1.0 - medium.transmittance(v, u1 - u0);
        if absorbed > 0.0 {
            out.composite(light(u0), absorbed)?;
        }
    }
    ControlFlow::Continue(())
}

/// The translucent ground-truth renderer over one shell and one medium.
pub struct MediumTruth<'a> {
    walk: ShellWalk<'a>,
    medium: &'a Medium,
    light_step: f64,
}

impl<'a> MediumTruth<'a> {
    /// Prepares `shell` for rendering `medium`, with [`DEFAULT_LIGHT_STEP`].
    pub fn new(shell: &'a Shell, medium: &'a Medium) -> Self {
        MediumTruth {
            walk: ShellWalk::new(shell, medium.dims()),
            medium,
            light_step: DEFAULT_LIGHT_STEP,
        }
    }

    /// The same renderer holding the scattered light constant over at most `step` voxels.
    pub fn with_light_step(self, step: f64) -> Self {
        MediumTruth {
            light_step: step,
            ..self
        }
    }

    /// Calls `f(chord, prism)` on every chord of the ray within [`t_min`, `t_max`], in order
    /// along the ray, until it breaks.
    fn chords(
        &self,
        origin: DVec3,
        dir: DVec3,
        (t_min, t_max): (f64, f64),
        mut f: impl FnMut(&Chord, usize) -> ControlFlow<()>,
    ) {
        for (a, b, i) in self.walk.intervals(origin, dir, t_min, t_max) {
            if self
                .walk
                .chords(i, origin, dir, (a, b), |c| f(c, i))
                .is_some()
            {
                return;
            }
        }
    }

    /// Transmittance of the shell along `origin + t·dir` (unit `dir`), t ∈ [`t_min`, `t_max`].
    pub fn transmittance(&self, origin: DVec3, dir: DVec3, t_min: f64, t_max: f64) -> f64 {
        let mut t = 1.0;
        self.chords(origin, dir, (t_min, t_max), |chord, _| {
            let [a, b] = chord.texture;
            let len = (b - a).length();
            t *= self
                .medium
                .segment_transmittance(a, (b - a) / len, len, MIN_TRANSMITTANCE / t);
            if t < MIN_TRANSMITTANCE {
                t = 0.0;
                ControlFlow::Break(())
            } else {
                ControlFlow::Continue(())
            }
        });
        t
    }

    /// What the camera ray `origin + t·dir` (unit `dir`), t ≥ 0, gathers under the scene's
    /// lights (shadows when the scene asks for them).
    pub fn gather(&self, shot: &Shot, origin: DVec3, dir: DVec3) -> Gathered {
        let shadows = shot.wants(Effect::Shadows);
        let scale = self.walk.scale();
        let mut out = Gathered::EMPTY;
        self.chords(origin, dir, (0.0, f64::INFINITY), |chord, i| {
            let prism = &self.walk.shell().prisms[i];
            let [a, b] = chord.texture;
            let len = (b - a).length();
            let view = (b - a) / len;
            self.medium.walk(a, view, len, |v, s0, s1| {
                integrate_voxel(self.medium, v, (s0, s1), self.light_step, &mut out, |u| {
                    let t = chord.t_at(u);
                    let point = origin + dir * t;
                    let texture = a + view * u;
                    // Texture voxel units → object.
                    let jacobian = prism
                        .jacobian(chord.point_at(u))
                        .map(|j| j * DMat3::from_diagonal(scale.recip()))
                        .filter(|j| j.determinant() != 0.0);
                    let inverse = jacobian.map(|j| j.inverse());
                    let normal = self.medium.material().normal_at(texture).and_then(|n| {
                        inverse.and_then(|inv| (inv.transpose() * n).try_normalize())
                    });
                    shade_transmitted(
                        &shot.lights,
                        &shot.material,
                        point,
                        normal,
                        self.medium.colour(v),
                        -dir,
                        |_, inc| {
                            if !shadows {
                                return 1.0;
                            }
                            // The object distance that is SHADOW_START voxels towards the light.
                            let start = inverse
                                .map_or(0.0, |inv| SHADOW_START / (inv * inc.direction).length());
                            if start >= inc.distance {
                                return 1.0;
                            }
                            self.transmittance(point, inc.direction, start, inc.distance)
                        },
                    )
                })
            })
        });
        out
    }

    /// The camera ray's composited radiance, or `None` where it met no medium.
    pub fn radiance(&self, shot: &Shot, origin: DVec3, dir: DVec3) -> Option<DVec3> {
        let g = self.gather(shot, origin, dir);
        (g.transmittance < 1.0).then_some(g.radiance)
    }
}
