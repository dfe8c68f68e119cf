//! VESTA iso-surfaces (placeholder during development).
mod table;
pub use table::{CycleType, cycle_types};
