//! Surfaces the mesostructure is mapped onto: base meshes ([`base_mesh`]: OBJ and built-in
//! shapes), the shell of prisms extruded from them ([`shell`]), and the explicit geometry of
//! a mesh tile mapped through that shell ([`explicit`]).

pub mod base_mesh;
pub mod curvature;
pub mod explicit;
pub mod shell;
