//! The vessel models the filter runs: the seed's kinematic model and the
//! extended kinetic twins.

pub mod effects;
pub mod kinematic;
pub mod otter_twin;
pub mod water_kinematic;
