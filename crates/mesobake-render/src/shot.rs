//! What one image shows and how, as the renderers read it: the camera, the lights, the
//! material's reflectance, the effects called for, and the knobs of the real-time GDM and
//! VDM algorithms. A scene file
//! makes one (`Scene::shot` in the binary); the renderers never see the file.

use mesobake_bake::gi::rtv::Glossy;
use mesobake_core::camera::Camera;
use mesobake_core::effect::Effect;
use mesobake_core::light::{Light, MaterialParams};
use mesobake_core::quality::{Quality, ShadowMethod};

/// The camera, lights, material, effects and algorithm knobs of one render.
#[derive(Clone, Debug)]
pub struct Shot {
    /// Where the image is seen from, its size and samples per pixel.
    pub camera: Camera,
    /// The lights that shade it.
    pub lights: Vec<Light>,
    /// The material's reflectance.
    pub material: MaterialParams,
    /// The effects called for: nothing else is shaded.
    pub effects: Vec<Effect>,
    /// The GDM per-pixel algorithm's accuracy knobs.
    pub quality: Quality,
    /// GDM refinement queries per hit.
    pub gdm_refinements: u32,
    /// Height-field texels the VDM's refinement walks (0: the lookup alone).
    pub vdm_refine_texels: u32,
    /// How the VDM tests a light's visibility.
    pub vdm_shadows: ShadowMethod,
}

impl Shot {
    /// Whether `effect` is called for.
    pub fn wants(&self, effect: Effect) -> bool {
        self.effects.contains(&effect)
    }

    /// The material's specular lobe under the environment light, where the shot calls for
    /// environment gloss (Blinn–Phong exponent n ≈ Phong exponent 4·s).
    pub fn environment_gloss(&self) -> Option<Glossy> {
        self.wants(Effect::EnvironmentGloss).then(|| Glossy {
            specular: self.material.specular,
            exponent: self.material.shininess / 4.0,
        })
    }
}
