//! The commands of the `mesobake` binary, one file per command or small group, each with its
//! options beside the code that runs it; [`output`] holds what they share (progress bars,
//! JSON summaries).

pub mod bench;
pub mod codec;
pub mod explicit;
pub mod gdm;
pub mod output;
pub mod package;
pub mod preview;
pub mod render;
pub mod report;
pub mod sample;
pub mod server;
pub mod vdm;
