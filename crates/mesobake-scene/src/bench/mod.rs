//! Benchmarks (`mesobake bench`): speed and memory against baselines measured in the same run.
//! Bakes, SVD and packages ([`bakes`]), the real-time preview
//! ([`preview`]), VDM against GDM on a height-field scene ([`vdm`]), the translucent-media
//! pipeline on the paper's largest case ([`media`]), and the heap counter they read
//! ([`counting_alloc`]).

pub mod bakes;
pub mod counting_alloc;
pub mod media;
pub mod preview;
pub mod vdm;
