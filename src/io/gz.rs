//! gzip helpers (to be written).
