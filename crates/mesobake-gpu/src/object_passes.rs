//! What the passes of several objects share, whatever each object's technique: the hit
//! targets and per-pixel nearest hit of the hit pass, the occlusion between objects
//! (`shaders/objects_on.wgsl`), and the order of the full-screen passes.

use super::target::HitTargets;
use glam::DVec3;

/// The most lights a scene of several objects with shadows may have: the occlusion pass
/// keeps one bit per light and pixel (`objects_on.wgsl`).
pub(super) const MAX_OCCLUDED_LIGHTS: usize = 32;

/// What the start, occlusion and shading passes of several objects share.
pub(super) struct SharedOcclusion {
    /// Per pixel, its hit's shadow-ray start (`hit_starts`).
    pub(super) starts: wgpu::TextureView,
    /// Per pixel, the bits of the lights another object blocks (`blocked`), cleared before
    /// each frame.
    pub(super) blocked: wgpu::Buffer,
}

/// The full-screen passes every object runs after the hit pass, in this order.
#[derive(Clone, Copy)]
pub(super) enum FullScreenStage {
    /// With occluders: the shadow-ray starts of the object's pixels (`fs_start`).
    Start,
    /// With occluders: the object against the others' shadow rays (`fs_occlude`).
    Occlude,
    /// The shading of the object's pixels (`fs_shade`).
    Shade,
}

/// What an object's passes draw into and read, shared by every object.
pub(super) struct SharedTargets<'a> {
    pub(super) hits: &'a HitTargets,
    pub(super) nearest_hit: &'a wgpu::Buffer,
    pub(super) occlusion: Option<&'a SharedOcclusion>,
    /// Every object's shell corners, which the projection's depth range encloses.
    pub(super) corners: &'a [DVec3],
}
