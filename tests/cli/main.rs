//! The command line (the `mesobake` binary) end to end. One test binary per crate under test, so
//! that the suite links few; one module per subject.

#[path = "../common/mod.rs"]
mod common;
#[path = "../../crates/mesobake-package/tests/support/mod.rs"]
mod package_support;

mod cli;
mod cli_package;
mod cli_preview;
mod cli_render;
