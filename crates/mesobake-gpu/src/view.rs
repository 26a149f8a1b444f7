//! What every real-time pipeline tells its shaders of the view: the `View` uniform (camera,
//! projection, material's specular, object index) and the `Light` records of `common.wgsl`,
//! and the view's buffer, which a supersampled preview rewrites per sample.

use super::gpu::Gpu;
use bytemuck::{Pod, Zeroable};
use glam::dcamera::rh;
use glam::{DMat4, DVec3};
use mesobake_core::camera::Camera;
use mesobake_core::light::Light;
use mesobake_render::shot::Shot;
use wgpu::util::DeviceExt;

/// The shader's `View`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub(super) struct ViewUniform {
    view_proj: [[f32; 4]; 4],
    eye: [f32; 4],
    specular: [f32; 4],
    light_count: u32,
    width: u32,
    object: u32,
    _pad: u32,
}

/// The shader's `Light`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub(super) struct LightRecord {
    kind: u32,
    _pad: [u32; 3],
    vector: [f32; 4],
    colour: [f32; 4],
}

fn light_record(light: &Light) -> LightRecord {
    let (kind, vector, colour) = match *light {
        Light::Point {
            position,
            intensity,
        } => (0, position, intensity),
        Light::Directional {
            direction,
            irradiance,
        } => (1, direction, irradiance),
        Light::Ambient { radiance } => (2, [0.0; 3], radiance),
    };
    let v = |a: [f64; 3]| [a[0] as f32, a[1] as f32, a[2] as f32, 0.0];
    LightRecord {
        kind,
        _pad: [0; 3],
        vector: v(vector),
        colour: v(colour),
    }
}

impl ViewUniform {
    /// The same view for object number `index` of a scene (`View.object`).
    pub(super) fn of_object(self, index: usize) -> ViewUniform {
        ViewUniform {
            object: index as u32,
            ..self
        }
    }
}

/// The shader's `View` for `scene`, its depth range around the points `bounds`.
pub(super) fn view_uniform(shot: &Shot, bounds: impl Iterator<Item = DVec3>) -> ViewUniform {
    let m = &shot.material;
    ViewUniform {
        view_proj: view_projection(&shot.camera, bounds)
            .as_mat4()
            .to_cols_array_2d(),
        eye: DVec3::from(shot.camera.eye)
            .extend(0.0)
            .as_vec4()
            .to_array(),
        specular: [
            m.specular[0] as f32,
            m.specular[1] as f32,
            m.specular[2] as f32,
            m.shininess as f32,
        ],
        light_count: shot.lights.len() as u32,
        width: shot.camera.width,
        object: 0,
        _pad: 0,
    }
}

/// A view uniform's buffer, which a supersampled preview rewrites for each sample so that
/// the rays pass through the sample's sub-pixel position (`render::sampling`).
pub(super) struct ViewBuffer {
    /// The uniform buffer (the shaders' `view`).
    pub(super) buffer: wgpu::Buffer,
    centre: ViewUniform,
    size: [f64; 2],
}

impl ViewBuffer {
    /// The buffer of `view` (rays through pixel centres) for `camera`'s image.
    pub(super) fn new(d: &wgpu::Device, view: ViewUniform, camera: &Camera) -> ViewBuffer {
        ViewBuffer {
            buffer: d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("view"),
                contents: bytemuck::bytes_of(&view),
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            }),
            centre: view,
            size: [f64::from(camera.width), f64::from(camera.height)],
        }
    }

    /// Moves the rays to `offset` in each pixel (from its top-left corner): the image is
    /// shifted by the offset's distance from the centre, so that the fragment at a pixel's
    /// centre sees what lies at `offset`.
    pub(super) fn set_subpixel(&self, gpu: &Gpu, offset: [f64; 2]) {
        let [w, h] = self.size;
        let shift = DVec3::new(
            2.0 * (0.5 - offset[0]) / w,
            2.0 * (offset[1] - 0.5) / h,
            0.0,
        );
        let view_proj = DMat4::from_translation(shift)
            * glam::Mat4::from_cols_array_2d(&self.centre.view_proj).as_dmat4();
        let view = ViewUniform {
            view_proj: view_proj.as_mat4().to_cols_array_2d(),
            ..self.centre
        };
        gpu.queue
            .write_buffer(&self.buffer, 0, bytemuck::bytes_of(&view));
    }
}

/// The shader's lights for `scene` (one zeroed record when it has none: a storage buffer
/// may not be empty).
pub(super) fn light_records(shot: &Shot) -> Vec<LightRecord> {
    let mut lights: Vec<LightRecord> = shot.lights.iter().map(light_record).collect();
    if lights.is_empty() {
        lights.push(LightRecord::zeroed());
    }
    lights
}

/// The camera's view-projection matrix (wgpu clip space, depth 0..1) with near and far
/// planes around the points `bounds` (the shell's corners).
fn view_projection(camera: &Camera, bounds: impl Iterator<Item = DVec3>) -> DMat4 {
    let eye = DVec3::from(camera.eye);
    let forward = (DVec3::from(camera.target) - eye).normalize();
    let (mut near, mut far) = (f64::INFINITY, 0.0f64);
    for p in bounds {
        let depth = (p - eye).dot(forward);
        near = near.min(depth);
        far = far.max(depth);
    }
    let far = if far > 0.0 { far * 1.01 } else { 1.0 };
    let near = near.max(far * 1e-4) * 0.99;
    let aspect = camera.width as f64 / camera.height as f64;
    // WebGPU's clip space: depth 0..1, y up (the DirectX convention).
    let proj = rh::proj::directx::perspective(camera.fov_y_degrees.to_radians(), aspect, near, far);
    proj * rh::view::look_at_mat4(eye, DVec3::from(camera.target), DVec3::from(camera.up))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::variant::source_with_every_struct;
    use crate::wgsl_twin::{assert_twin, rust_layout};

    /// The view and light records are laid out as `View` and `Light` in `common.wgsl`.
    #[test]
    fn the_view_and_light_records_are_their_wgsl_structs() {
        let source = source_with_every_struct();
        let view = rust_layout!(ViewUniform {
            view_proj,
            eye,
            specular,
            light_count,
            width,
            object
        });
        assert_twin(&source, "View", view);
        assert_twin(
            &source,
            "Light",
            rust_layout!(LightRecord {
                kind,
                vector,
                colour
            }),
        );
    }
}
