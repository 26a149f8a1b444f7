//! The Monte Carlo path tracer: the ground truth for environment lighting. Camera rays and
//! every bounce go through the ground-truth renderer's exact mapping into the real
//! mesostructure ([`TruthRenderer`]); a ray that meets no mesostructure is tested against the
//! base mesh (opaque) and otherwise brings the environment map's radiance in its direction
//! (the full-resolution map, not its SH projection).
//!
//! At each hit the incident light is estimated with `samples` cosine-distributed directions
//! (so each estimate is albedo × the sampled radiance: ρ/π·∫L cos dω has pdf cos/π), each
//! followed as one path of at most `depth` bounces, every surface Lambertian with the
//! material volume's albedo. Local lights are shaded as the ground truth does. The random
//! numbers are seeded from the camera ray, so images are reproducible.

use super::truth::{Surface, TruthRenderer};
use crate::error::{Error, Result};
use crate::gi::environment::Environment;
use crate::gi::prt::Occluder;
use crate::scene::{Effect, LoadedScene, Scene};
use glam::DVec3;
use std::f64::consts::TAU;

/// The path tracer over one loaded scene.
pub struct PathTracer<'a> {
    truth: TruthRenderer<'a>,
    base: Occluder,
    environment: &'a Environment,
    samples: u32,
    depth: u32,
}

impl<'a> PathTracer<'a> {
    /// Prepares `loaded` (which must have an environment) with `samples` paths per pixel of
    /// at most `depth` bounces.
    pub fn new(loaded: &'a LoadedScene, samples: u32, depth: u32) -> Result<PathTracer<'a>> {
        let environment = loaded.environment.as_ref().ok_or_else(|| {
            Error::Scene("the path tracer needs a scene with environment lighting".into())
        })?;
        if samples == 0 || depth == 0 {
            return Err(Error::InvalidParameter(format!(
                "path tracing needs at least one sample and one bounce, got {samples} and {depth}"
            )));
        }
        Ok(PathTracer {
            truth: TruthRenderer::new(
                &loaded.shell,
                loaded.mesostructure.caster(),
                &loaded.material,
            ),
            base: Occluder::new(&loaded.base),
            environment,
            samples,
            depth,
        })
    }

    /// The radiance along the camera ray, or `None` for a miss.
    pub fn radiance(&self, scene: &Scene, origin: DVec3, dir: DVec3) -> Option<DVec3> {
        let hit = self.truth.trace(origin, dir, 0.0, f64::INFINITY)?;
        let surface = self.truth.surface(&hit, origin, dir);
        let local = self.truth.shade_lights(scene, &surface, dir);
        if !scene.wants(Effect::EnvironmentLighting) {
            return Some(local);
        }
        let mut rng = Rng::from_ray(origin, dir);
        let mut sum = DVec3::ZERO;
        for _ in 0..self.samples {
            sum += self.incident(&surface, &mut rng, 1);
        }
        Some(local + surface.albedo * sum / f64::from(self.samples))
    }

    /// One sample of the light arriving at `from` along a cosine-distributed direction.
    fn incident(&self, from: &Surface, rng: &mut Rng, depth: u32) -> DVec3 {
        let w = cosine_direction(from.normal, rng);
        match self.truth.trace(from.start, w, 0.0, f64::INFINITY) {
            Some(hit) if depth < self.depth => {
                let next = self.truth.surface(&hit, from.start, w);
                next.albedo * self.incident(&next, rng, depth + 1)
            }
            Some(_) => DVec3::ZERO,
            None if self.base.blocked(from.start, w) => DVec3::ZERO,
            None => DVec3::from(self.environment.radiance(w)),
        }
    }
}

/// A direction around unit `n` with density cos θ / π.
fn cosine_direction(n: DVec3, rng: &mut Rng) -> DVec3 {
    let (u1, u2) = (rng.uniform(), rng.uniform());
    let (r, phi) = (u1.sqrt(), TAU * u2);
    let (t, b) = n.any_orthonormal_pair();
    (t * (r * phi.cos()) + b * (r * phi.sin()) + n * (1.0 - u1).max(0.0).sqrt()).normalize()
}

/// SplitMix64: small, fast and good enough for sampling directions.
struct Rng(u64);

impl Rng {
    /// A generator seeded from the bits of a ray.
    fn from_ray(origin: DVec3, dir: DVec3) -> Rng {
        let seed = [origin.x, origin.y, origin.z, dir.x, dir.y, dir.z]
            .iter()
            .fold(0x9E37_79B9_7F4A_7C15u64, |h, v| {
                (h ^ v.to_bits()).wrapping_mul(0xBF58_476D_1CE4_E5B9)
            });
        Rng(seed)
    }

    /// Uniform in [0, 1).
    fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }
}
