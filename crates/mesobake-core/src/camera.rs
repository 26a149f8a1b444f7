//! The pinhole camera and its image plane: where each pixel's rays go.

use crate::error::{Error, Result};
use crate::limits::MAX_IMAGE_SIDE;
use crate::samples_per_pixel::{MAX_IMAGE_SAMPLES, SamplesPerPixel};
use glam::DVec3;
use serde::{Deserialize, Serialize};

/// A pinhole camera.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Camera {
    /// Eye position.
    pub eye: [f64; 3],
    /// The point looked at (centre of the image).
    pub target: [f64; 3],
    /// Up direction (need not be orthogonal to the view).
    #[serde(default = "default_up")]
    pub up: [f64; 3],
    /// Vertical field of view in degrees.
    pub fov_y_degrees: f64,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Camera rays averaged per pixel (see [`crate::samples_per_pixel`]); 1, the pixel's centre, by
    /// default.
    #[serde(default, skip_serializing_if = "SamplesPerPixel::is_one")]
    pub samples_per_pixel: SamplesPerPixel,
    /// Where in each pixel [`Camera::ray`] passes, from its top-left corner in pixels: the
    /// centre, unless a supersampled render moves it to one of its samples.
    #[serde(skip, default = "pixel_centre")]
    pub subpixel: [f64; 2],
}

fn pixel_centre() -> [f64; 2] {
    [0.5, 0.5]
}

fn default_up() -> [f64; 3] {
    [0.0, 1.0, 0.0]
}

/// A camera's eye and its image plane at unit distance along the view: the pixel at
/// continuous image position (x, y) (pixel centres at half-integers, row 0 at the top) looks
/// along `forward + right·sx + up·sy`, sx = (2x/width − 1)·`half_width`,
/// sy = (1 − 2y/height)·`half_height`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImagePlane {
    /// Eye position.
    pub eye: DVec3,
    /// Unit viewing direction.
    pub forward: DVec3,
    /// Unit image-right direction.
    pub right: DVec3,
    /// Unit image-up direction.
    pub up: DVec3,
    /// Half the image plane's width at unit distance.
    pub half_width: f64,
    /// Half its height (tan of half the vertical field of view).
    pub half_height: f64,
    size: [f64; 2],
    subpixel: [f64; 2],
}

impl ImagePlane {
    /// Where `point` projects to, as a continuous image position (see [`ImagePlane`]), or
    /// `None` if it does not lie in front of the eye.
    pub fn project(&self, point: DVec3) -> Option<[f64; 2]> {
        let d = point - self.eye;
        let z = d.dot(self.forward);
        (z > 0.0).then(|| {
            let sx = d.dot(self.right) / (z * self.half_width);
            let sy = d.dot(self.up) / (z * self.half_height);
            [
                (sx + 1.0) * 0.5 * self.size[0],
                (1.0 - sy) * 0.5 * self.size[1],
            ]
        })
    }

    /// The unit direction through pixel (`x`, `y`) at the camera's sub-pixel position (its
    /// centre unless supersampling moved it).
    pub fn pixel_direction(&self, x: u32, y: u32) -> DVec3 {
        self.direction_at(x, y, self.subpixel)
    }

    /// The unit direction through pixel (`x`, `y`) at `offset` from its top-left corner.
    pub fn direction_at(&self, x: u32, y: u32, offset: [f64; 2]) -> DVec3 {
        // In the camera's historical association, so that images stay bit for bit.
        let aspect = self.size[0] / self.size[1];
        let sx = ((x as f64 + offset[0]) / self.size[0] * 2.0 - 1.0) * self.half_height * aspect;
        let sy = (1.0 - (y as f64 + offset[1]) / self.size[1] * 2.0) * self.half_height;
        (self.forward + self.right * sx + self.up * sy).normalize()
    }

    /// How far, in the image plane at unit distance, the camera's sub-pixel position lies
    /// from the pixel's centre: what moves a pipeline that casts through pixel centres onto
    /// the sub-pixel position.
    pub fn subpixel_shift(&self) -> DVec3 {
        let [ox, oy] = self.subpixel;
        self.right * ((ox - 0.5) * 2.0 * self.half_width / self.size[0])
            - self.up * ((oy - 0.5) * 2.0 * self.half_height / self.size[1])
    }
}

impl Camera {
    /// The eye and image plane.
    pub fn image_plane(&self) -> ImagePlane {
        let eye = DVec3::from(self.eye);
        let forward = (DVec3::from(self.target) - eye).normalize();
        let right = forward.cross(DVec3::from(self.up)).normalize();
        let half_height = (self.fov_y_degrees.to_radians() * 0.5).tan();
        ImagePlane {
            eye,
            forward,
            right,
            up: right.cross(forward),
            half_width: half_height * self.width as f64 / self.height as f64,
            half_height,
            size: [self.width as f64, self.height as f64],
            subpixel: self.subpixel,
        }
    }

    /// Sets the samples per pixel, refusing an image whose rays would exceed
    /// [`MAX_IMAGE_SAMPLES`] in all.
    pub fn set_samples_per_pixel(&mut self, spp: SamplesPerPixel) -> Result<()> {
        spp.check_image(self.width, self.height, MAX_IMAGE_SAMPLES)?;
        self.samples_per_pixel = spp;
        Ok(())
    }

    /// This camera with its rays through `offset` in each pixel (from the top-left corner).
    pub fn at_subpixel(&self, offset: [f64; 2]) -> Camera {
        Camera {
            subpixel: offset,
            ..*self
        }
    }

    /// Eye, and the unit direction through pixel (`x`, `y`) (row 0 at the top) at the
    /// camera's sub-pixel position.
    pub fn ray(&self, x: u32, y: u32) -> (DVec3, DVec3) {
        let plane = self.image_plane();
        (plane.eye, plane.pixel_direction(x, y))
    }

    /// Refuses a camera that cannot form an image, naming the field.
    pub fn validate(&self) -> Result<()> {
        let vectors = [self.eye, self.target, self.up];
        if !vectors.iter().flatten().all(|c| c.is_finite()) {
            return Err(Error::Scene("camera: non-finite eye, target or up".into()));
        }
        let forward = DVec3::from(self.target) - DVec3::from(self.eye);
        if forward.length_squared() == 0.0 {
            return Err(Error::Scene("camera: eye and target coincide".into()));
        }
        if forward.normalize().cross(DVec3::from(self.up)).length() < 1e-9 {
            return Err(Error::Scene(
                "camera: up is parallel to the viewing direction (or zero)".into(),
            ));
        }
        if !(self.fov_y_degrees > 0.0 && self.fov_y_degrees < 179.0) {
            return Err(Error::Scene(format!(
                "camera: fov_y_degrees must be in (0, 179), got {}",
                self.fov_y_degrees
            )));
        }
        for (name, side) in [("width", self.width), ("height", self.height)] {
            if side == 0 || side > MAX_IMAGE_SIDE {
                return Err(Error::Scene(format!(
                    "camera: {name} must be in 1..={MAX_IMAGE_SIDE}, got {side}"
                )));
            }
        }
        self.samples_per_pixel
            .check_image(self.width, self.height, MAX_IMAGE_SAMPLES)
            .map_err(|e| Error::Scene(format!("camera: {e}")))
    }
}
