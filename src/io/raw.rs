//! Raw reader (to be written).

use std::path::Path;

use crate::error::{Error, Result};
use crate::io::{Image, ReadOptions};

/// Reads a raw file.
pub fn read(path: &Path, _opts: &ReadOptions) -> Result<Image> {
    Err(Error::input(path, "raw reading is not implemented yet"))
}
