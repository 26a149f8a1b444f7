//! Bakes and packages (`mesobake-bake` over the format crate): the GDM, VDM and samples against
//! analytic references, the truncated SVD, packages, explicit geometry, bad input. One test binary
//! per crate under test, so that the suite links few; one module per subject.

#[path = "../common/mod.rs"]
mod common;
#[path = "../common/package_edit.rs"]
mod package_edit;
#[path = "../../crates/mesobake-package/tests/support/mod.rs"]
mod package_support;

mod bad_input;
mod explicit;
mod gdm_exact;
mod gdm_fast;
mod gltf_base_mesh;
mod openvdb_import;
mod package;
mod samples;
mod svd;
mod vdm;
