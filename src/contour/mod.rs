//! DICONEX: contours of 2-D images and of slices of volumes, the 2-D
//! analogue of VESTA (`septa contour`).
//!
//! This module owns the 2-D contour work:
//! - [`diconex`]: the algorithm — iso-contours of gray values
//!   ([`iso_contours`]) and per-label-pair polylines of label images
//!   ([`label_contours`]) meeting at shared junction points;
//! - [`contour_io`]: the writers of its results (SVG, with label colours from
//!   [`crate::render::palette`] and a legend; CSV; JSON).
//!
//! Its inputs, [`Image2d`] (PGM/PBM and PNG files, or one slice of any
//! volume septa reads), are read by [`crate::io::image2d`] and re-exported
//! here. The ambiguity [`Mode`] is VESTA's ([`crate::iso::Mode`]), and so is
//! the interpolation of support points.

pub mod contour_io;
pub mod diconex;

pub use crate::io::image2d::{Image2d, Slice, is_image_file, read_image2d, slice};
pub use crate::iso::Mode;
pub use contour_io::{ContourFormat, write_contours, write_label_contours};
pub use diconex::{
    Contour, ContourOptions, Contours, LabelContourOptions, LabelContours, Polyline, iso_contours,
    label_contours,
};
