//! mesobake's bakes and everything they read: the mesostructure inputs ([`mesostructure`]:
//! volumes, OBJ tiles, height fields, translucent media), the surfaces they are mapped onto
//! ([`surface`]: base meshes, the shell of prisms, explicit geometry), the bakes themselves
//! (the generalized displacement map [`gdm`], the view-dependent displacement map [`vdm`],
//! global illumination's radiance transfer [`gi`]), their compression ([`compress`]) and
//! their packages ([`package`]: encoding them in the format of crate `mesobake-package`,
//! and decoding them for the renderers).
//! It knows nothing of scene files, cameras, renderers, GPUs, HTTP or SQL; only the core and
//! the package format lie below it.
//!
//! ```
//! use mesobake_bake::gdm::{self, volume_caster::VolumeCaster};
//! use mesobake_package::grid::{DirectionGrid, Dims};
//! use mesobake_core::limits::Limits;
//! use mesobake_bake::mesostructure::volume::Volume;
//!
//! // A floor: layer 0 of an 8×8×4 volume is solid.
//! let limits = Limits::default();
//! let volume = Volume::from_fn(Dims::new(8, 8, 4)?, &limits, |_, _, k| k == 0)?;
//! let dirs = DirectionGrid::new(2, 4)?; // θ = 45° (up) and 135° (down)
//! let g = gdm::exact::bake(&VolumeCaster::new(&volume), dirs, &limits, &())?;
//! // From the centre of layer 2 (z = 2.5), looking down at 45°, the floor (z = 1) is
//! // 1.5·√2 away; looking up, the ray escapes.
//! assert!((g.get(3, 3, 2, 1, 0) - 1.5 * 2f32.sqrt()).abs() < 1e-5);
//! assert!(g.get(3, 3, 2, 0, 0).is_infinite());
//! assert_eq!(g.get(3, 3, 0, 1, 0), 0.0);
//! # Ok::<(), mesobake_core::Error>(())
//! ```

pub mod compress;
pub mod gdm;
pub mod gi;
pub mod mesostructure;
pub mod package;
pub mod surface;
pub mod vdm;
