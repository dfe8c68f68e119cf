//! nifti reader and label writer (to be written).

use std::path::Path;

use crate::error::{Error, Result};
use crate::io::Image;
use crate::volume::LabelVolume;

/// Reads a nifti file.
pub fn read(path: &Path) -> Result<Image> {
    Err(Error::input(path, "nifti reading is not implemented yet"))
}

/// Writes a label volume as nifti.
pub fn write_labels(path: &Path, _volume: &LabelVolume) -> Result<()> {
    Err(Error::input(path, "nifti writing is not implemented yet"))
}
