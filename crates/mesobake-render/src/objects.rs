//! Several objects in one image: each object's renderer finds its own first hit, the nearest
//! is shaded, and a light reaches it only if its own shadow test passes and no other object
//! blocks the shadow ray before the light ([`ObjectRenderer::occludes`]). The ground truth
//! composes its exact renderers this way; the real-time specification composes the objects'
//! real-time renderers (GDM, VDM), each object's own hit query answering for the shadow rays
//! that cross it.

use crate::lighting::Incident;
use crate::shot::Shot;
use glam::DVec3;

/// What compositing asks of one object's renderer.
pub trait ObjectRenderer: Sync {
    /// The ray parameter of the first hit along `origin + t·dir` (unit `dir`), if any, with
    /// the knobs of `shot` (the object's).
    fn hit_distance(&self, shot: &Shot, origin: DVec3, dir: DVec3) -> Option<f64>;

    /// Whether the object blocks the shadow ray from `start` along unit `dir` within
    /// `distance`: by default, whether its first hit lies nearer.
    fn occludes(&self, shot: &Shot, start: DVec3, dir: DVec3, distance: f64) -> bool {
        self.hit_distance(shot, start, dir)
            .is_some_and(|t| t < distance)
    }

    /// The shaded radiance of the first hit, a light reaching it only where the object's own
    /// shadow test and `elsewhere(shadow ray start, incident light)` both say it does.
    fn radiance_with(
        &self,
        shot: &Shot,
        origin: DVec3,
        dir: DVec3,
        elsewhere: &dyn Fn(DVec3, &Incident) -> bool,
    ) -> Option<DVec3>;
}

/// One object to composite: its renderer and what it renders with (its own material).
pub struct Object<'a> {
    /// The object's renderer.
    pub renderer: &'a dyn ObjectRenderer,
    /// The shot with the object's material.
    pub shot: &'a Shot,
}

/// The radiance along the ray through several objects: the nearest object's, with the others
/// casting shadows on it (where the shot calls for shadows).
pub fn radiance(objects: &[Object], origin: DVec3, dir: DVec3) -> Option<DVec3> {
    let (nearest, _) = objects
        .iter()
        .enumerate()
        .filter_map(|(i, o)| Some((i, o.renderer.hit_distance(o.shot, origin, dir)?)))
        .min_by(|a, b| a.1.total_cmp(&b.1))?;
    let object = &objects[nearest];
    let shadows = object.shot.wants(mesobake_core::effect::Effect::Shadows);
    let elsewhere = |start: DVec3, inc: &Incident| {
        !shadows
            || objects.iter().enumerate().all(|(i, o)| {
                i == nearest
                    || !o
                        .renderer
                        .occludes(o.shot, start, inc.direction, inc.distance)
            })
    };
    object
        .renderer
        .radiance_with(object.shot, origin, dir, &elsewhere)
}
