//! What each setting costs and buys, measured against exact references: `mesobake report
//! accuracy` ([`accuracy`]: GDM compression), `report render` ([`render`]: the GDM renderer
//! against the truth, and its error budget) and `report gi` ([`gi`]: radiance transfer).

pub mod accuracy;
pub mod gi;
pub mod render;
