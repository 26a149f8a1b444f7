//! The Monte Carlo path tracer: the ground truth for environment lighting. Camera rays and
//! every bounce go through the ground-truth renderer's exact mapping into the real
//! mesostructure ([`TruthRenderer`]); a ray that meets no mesostructure is tested against the
//! base mesh (opaque) and otherwise brings the environment map's radiance in its direction
//! (the full-resolution map, not its SH projection).
//!
//! At each hit the reflected light is estimated with `samples` paths of at most `depth`
//! bounces. Every surface reflects as the RTV models it ([`mesobake_bake::gi::rtv`]): Lambert with the
//! material volume's albedo ρ, plus, when the scene calls for `environment_gloss`, the
//! normalized Phong lobe k_s·(s+1)/(2π)·cos^s α about the mirror direction (s = shininess/4,
//! no cosine at the light, nothing from below the surface). Each bounce picks one lobe, the
//! diffuse one with probability P = ρ̄/(ρ̄ + k̄_s) (channel means), and samples its own density:
//! cosine-distributed directions or the Phong lobe, weighted by the reflectance over the
//! lobes' mixture density. Beside it, every bounce draws one direction from the environment
//! map itself ([`EnvironmentSampler`]: next-event estimation, so a small bright sun is found
//! by most paths rather than by rare ones); the two are combined by the balance heuristic
//! (multiple importance sampling), which keeps the estimate unbiased. Local lights are shaded
//! as the ground truth does. The random numbers are seeded from the camera ray, so images are
//! reproducible.

use super::environment_sampler::EnvironmentSampler;
use super::truth::{Surface, TruthRenderer};
use crate::shot::Shot;
use glam::DVec3;
use mesobake_bake::gi::environment::Environment;
use mesobake_bake::gi::prt::Occluder;
use mesobake_bake::surface::base_mesh::BaseMesh;
use mesobake_core::effect::Effect;
use mesobake_core::error::{Error, Result};
use std::f64::consts::{PI, TAU};

/// The glossy lobe of the environment light's BRDF.
#[derive(Clone, Copy, Debug)]
struct Gloss {
    specular: DVec3,
    exponent: f64,
}

/// The path tracer over one shell and its mesostructure.
pub struct PathTracer<'a> {
    truth: TruthRenderer<'a>,
    base: Occluder,
    environment: &'a Environment,
    sampler: EnvironmentSampler<'a>,
    samples: u32,
    depth: u32,
    gloss: Option<Gloss>,
}

impl<'a> PathTracer<'a> {
    /// Traces `truth`'s mesostructure over the base mesh `base` (which shadows the
    /// `environment`), lit as `shot` says, with `samples` paths per pixel of at most `depth`
    /// bounces.
    pub fn new(
        truth: TruthRenderer<'a>,
        base: &BaseMesh,
        environment: Option<&'a Environment>,
        shot: &Shot,
        samples: u32,
        depth: u32,
    ) -> Result<PathTracer<'a>> {
        let environment = environment.ok_or_else(|| {
            Error::Scene("the path tracer needs a scene with environment lighting".into())
        })?;
        if samples == 0 || depth == 0 {
            return Err(Error::InvalidParameter(format!(
                "path tracing needs at least one sample and one bounce, got {samples} and {depth}"
            )));
        }
        Ok(PathTracer {
            truth,
            base: Occluder::new(base),
            environment,
            sampler: EnvironmentSampler::new(environment),
            samples,
            depth,
            gloss: shot.environment_gloss().map(|g| Gloss {
                specular: DVec3::from(g.specular),
                exponent: g.exponent,
            }),
        })
    }

    /// The radiance along the camera ray, or `None` for a miss.
    pub fn radiance(&self, shot: &Shot, origin: DVec3, dir: DVec3) -> Option<DVec3> {
        let hit = self.truth.trace(origin, dir, 0.0, f64::INFINITY)?;
        let surface = self.truth.surface(&hit, origin, dir);
        let local = self.truth.shade_lights(shot, &surface, dir);
        if !shot.wants(Effect::EnvironmentLighting) {
            return Some(local);
        }
        let mut rng = Rng::from_ray(origin, dir);
        let mut sum = DVec3::ZERO;
        for _ in 0..self.samples {
            sum += self.reflected(&surface, dir, &mut rng, 1);
        }
        Some(local + sum / f64::from(self.samples))
    }

    /// One sample of the environment light that `at`, reached along `arriving`, reflects
    /// back along it: a light sample and a BRDF sample, weighted by the balance heuristic.
    fn reflected(&self, at: &Surface, arriving: DVec3, rng: &mut Rng, depth: u32) -> DVec3 {
        let mut sum = DVec3::ZERO;
        if let Some(light) = self
            .sampler
            .sample([rng.uniform(), rng.uniform(), rng.uniform()])
        {
            let (reflectance, pdf) = self.reflectance(at, arriving, light.direction);
            if reflectance != DVec3::ZERO && self.escapes(at.start, light.direction) {
                sum += reflectance * light.radiance * balance(light.pdf, pdf) / light.pdf;
            }
        }
        let w = match self.gloss {
            Some(g) if rng.uniform() >= diffuse_probability(at.albedo, g.specular) => {
                phong_direction(mirror(arriving, at.normal), g.exponent, rng)
            }
            _ => cosine_direction(at.normal, rng),
        };
        let (reflectance, pdf) = self.reflectance(at, arriving, w);
        if reflectance == DVec3::ZERO || pdf <= 0.0 {
            return sum;
        }
        let weight = reflectance / pdf;
        match self.truth.trace(at.start, w, 0.0, f64::INFINITY) {
            Some(hit) if depth < self.depth => {
                let next = self.truth.surface(&hit, at.start, w);
                sum + weight * self.reflected(&next, w, rng, depth + 1)
            }
            Some(_) => sum,
            None if self.base.blocked(at.start, w) => sum,
            None => {
                let mis = balance(pdf, self.sampler.pdf(w));
                sum + weight * DVec3::from(self.environment.radiance(w)) * mis
            }
        }
    }

    /// Whether a ray from `start` along `w` reaches the environment (no mesostructure, no
    /// base mesh).
    fn escapes(&self, start: DVec3, w: DVec3) -> bool {
        self.truth.trace(start, w, 0.0, f64::INFINITY).is_none() && !self.base.blocked(start, w)
    }

    /// What `at` reflects back along `arriving` of unit radiance from `w` (ρ/π·cos θ, plus
    /// the Phong lobe), and the density with which the BRDF sampling draws `w` (the lobes'
    /// mixture).
    fn reflectance(&self, at: &Surface, arriving: DVec3, w: DVec3) -> (DVec3, f64) {
        let cos = w.dot(at.normal);
        if cos <= 0.0 {
            return (DVec3::ZERO, 0.0);
        }
        let diffuse = cos / PI;
        match self.gloss {
            Some(g) => {
                let p = diffuse_probability(at.albedo, g.specular);
                let alpha = w.dot(mirror(arriving, at.normal)).max(0.0);
                let lobe = (g.exponent + 1.0) / TAU * alpha.powf(g.exponent);
                (
                    at.albedo * diffuse + g.specular * lobe,
                    p * diffuse + (1.0 - p) * lobe,
                )
            }
            None => (at.albedo * diffuse, diffuse),
        }
    }
}

/// The balance heuristic's weight of a strategy of density `own` beside one of `other`.
fn balance(own: f64, other: f64) -> f64 {
    own / (own + other)
}

/// `arriving` mirrored about unit `normal`.
fn mirror(arriving: DVec3, normal: DVec3) -> DVec3 {
    arriving - 2.0 * arriving.dot(normal) * normal
}

/// The probability of following the diffuse lobe: its share of the channel-mean reflectance.
fn diffuse_probability(albedo: DVec3, specular: DVec3) -> f64 {
    let (d, s) = (albedo.element_sum(), specular.element_sum());
    if d + s > 0.0 { d / (d + s) } else { 1.0 }
}

/// A direction around unit `axis` with density (s+1)/(2π)·cos^s α (the normalized Phong lobe).
fn phong_direction(axis: DVec3, exponent: f64, rng: &mut Rng) -> DVec3 {
    let (u1, u2) = (rng.uniform(), rng.uniform());
    let cos = (1.0 - u1).powf(1.0 / (exponent + 1.0));
    let sin = (1.0 - cos * cos).max(0.0).sqrt();
    let phi = TAU * u2;
    let (t, b) = axis.any_orthonormal_pair();
    (t * (sin * phi.cos()) + b * (sin * phi.sin()) + axis * cos).normalize()
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
