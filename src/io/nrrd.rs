//! nrrd reader and label writer (to be written).

use std::path::Path;

use crate::error::{Error, Result};
use crate::io::Image;
use crate::volume::LabelVolume;

/// Reads a nrrd file.
pub fn read(path: &Path) -> Result<Image> {
    Err(Error::input(path, "nrrd reading is not implemented yet"))
}

/// Writes a label volume as nrrd.
pub fn write_labels(path: &Path, _volume: &LabelVolume) -> Result<()> {
    Err(Error::input(path, "nrrd writing is not implemented yet"))
}
