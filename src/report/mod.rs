//! What each setting costs and buys, measured against exact references: `mesobake report
//! accuracy` ([`accuracy`]: GDM compression), `report codecs` ([`codecs`]: every GDM codec
//! and size on scenes, samples and images), `report render` ([`render`]: the GDM renderer
//! against the truth, and its error budget), `report quality` ([`quality`]: the per-pixel
//! algorithm's accuracy knobs against the truth, and their time), `report gi` ([`gi`]:
//! radiance transfer) and `report vdm` ([`vdm`]: the VDM's knobs, and the GDM beside it).

pub mod accuracy;
pub mod codecs;
pub mod gi;
pub mod plot;
pub mod quality;
pub mod render;
pub mod vdm;
