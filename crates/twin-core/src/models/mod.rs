//! The vessel models the filter runs: the seed's kinematic model and the
//! extended kinetic twins.

pub mod kinematic;
pub mod otter_twin;
