//! MetaImage reader (to be written).

use std::path::Path;

use crate::error::{Error, Result};
use crate::io::Image;

/// Reads a MetaImage file.
pub fn read(path: &Path) -> Result<Image> {
    Err(Error::input(path, "MetaImage reading is not implemented yet"))
}
