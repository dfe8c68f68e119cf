//! Writers for DICONEX contours: SVG (to look at), CSV (one row per point)
//! and JSON (everything, with physical coordinates for slices of volumes).
//! All are written atomically (a temporary file, then a rename).
//!
//! The label SVG fills each label's pixels in its colour from
//! [`crate::render::palette`] (the labels in increasing value take colours
//! 0, 1, 2, …), draws the polylines dark over them with the junction points,
//! and has a legend beside the image: label value → colour, the outside
//! label marked.
//!
//! Coordinates are pixel index coordinates (pixel centres at integers); for
//! slices of volumes the CSV and JSON also give LPS millimetres. The SVG's
//! user space is the pixel grid (`viewBox` from −0.5 to width − 0.5), so it
//! overlays the image; rows go down there, so counter-clockwise contours
//! (positive signed area) appear clockwise.

use std::io::Write;
use std::path::Path;

use glam::DVec2;

use super::diconex::{Contours, LabelContours};
use crate::error::{Error, Result};
use crate::io::atomic_write_with;
use crate::io::image2d::Image2d;

/// Output formats by extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ContourFormat {
    Svg,
    Csv,
    Json,
}

impl ContourFormat {
    /// The format of a path's extension.
    pub fn of(path: &Path) -> Result<Self> {
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .unwrap_or_default();
        match ext.as_str() {
            "svg" => Ok(ContourFormat::Svg),
            "csv" => Ok(ContourFormat::Csv),
            "json" => Ok(ContourFormat::Json),
            _ => Err(Error::input(
                path,
                "unknown contour format: use .svg, .csv or .json",
            )),
        }
    }
}

/// Shortest decimal that reads back to the same f64.
fn num(x: f64) -> String {
    format!("{x}")
}

fn svg_header(w: &mut dyn Write, width: usize, height: usize, title: &str) -> std::io::Result<()> {
    svg_header_with_legend(w, width, height, (0.0, 0.0), title)
}

/// The SVG header; `legend` the width and height (user units: pixels) of a
/// legend to the right of the image.
fn svg_header_with_legend(
    w: &mut dyn Write,
    width: usize,
    height: usize,
    legend: (f64, f64),
    title: &str,
) -> std::io::Result<()> {
    let (vw, vh) = (width as f64 + legend.0, (height as f64).max(legend.1));
    // 1 pixel = `scale` SVG units on screen; at least ~600 px wide
    let scale = (600.0 / width.max(height) as f64).max(1.0);
    writeln!(
        w,
        r##"<?xml version="1.0" encoding="UTF-8"?>
<svg xmlns="http://www.w3.org/2000/svg" width="{}" height="{}" viewBox="-0.5 -0.5 {vw} {vh}">
<title>{}</title>
<rect x="-0.5" y="-0.5" width="{width}" height="{height}" fill="white" stroke="#ccc" stroke-width="0.05"/>"##,
        (vw * scale).round(),
        (vh * scale).round(),
        xml_escape(title)
    )
}

/// The labels of a label image in increasing value (with `outside`), each
/// with its palette colour number (its rank).
fn label_colours(labels: &[i64], outside: i64) -> Vec<i64> {
    let mut v: Vec<i64> = labels.to_vec();
    v.push(outside);
    v.sort_unstable();
    v.dedup();
    v
}

/// The font size of the legend, in pixels of the image.
fn legend_font(width: usize, height: usize) -> f64 {
    width.max(height) as f64 / 30.0
}

/// Width of the legend (user units) for these labels.
fn legend_width(values: &[i64], font: f64) -> f64 {
    let chars = values
        .iter()
        .map(|v| format!("{v} (outside)").len())
        .max()
        .unwrap_or(0);
    font * (3.0 + 0.6 * chars as f64)
}

/// Each label's pixels as one filled path of row runs.
fn write_label_fills(
    w: &mut dyn Write,
    labels: &[i64],
    width: usize,
    values: &[i64],
) -> std::io::Result<()> {
    let mut runs: Vec<String> = vec![String::new(); values.len()];
    for (j, row) in labels.chunks(width).enumerate() {
        let mut i = 0;
        while i < row.len() {
            let l = row[i];
            let start = i;
            while i < row.len() && row[i] == l {
                i += 1;
            }
            let k = values.binary_search(&l).unwrap_or(0);
            let d = &mut runs[k];
            d.push_str(&format!(
                "M{} {}h{}v1h-{}z",
                start as f64 - 0.5,
                j as f64 - 0.5,
                i - start,
                i - start
            ));
        }
    }
    for (k, d) in runs.iter().enumerate() {
        if !d.is_empty() {
            writeln!(
                w,
                r#"<path class="label" data-label="{}" d="{d}" fill="{}" fill-opacity="0.45" stroke="none"/>"#,
                values[k],
                crate::render::palette::hex(k)
            )?;
        }
    }
    Ok(())
}

/// `x` to 3 decimals (legend positions: no need for every digit).
fn short(x: f64) -> String {
    num((x * 1000.0).round() / 1000.0)
}

/// The legend: a swatch and the value of each label, right of the image.
fn write_legend(
    w: &mut dyn Write,
    width: usize,
    values: &[i64],
    outside: i64,
    font: f64,
) -> std::io::Result<()> {
    let x = width as f64 - 0.5 + font;
    writeln!(
        w,
        r#"<g class="legend" font-family="sans-serif" font-size="{}">"#,
        short(font)
    )?;
    for (k, &v) in values.iter().enumerate() {
        let y = -0.5 + font * (0.5 + 1.5 * k as f64);
        writeln!(
            w,
            r##"<rect x="{}" y="{}" width="{f}" height="{f}" fill="{}" fill-opacity="0.45" stroke="#333" stroke-width="{}"/><text x="{}" y="{}">{v}{}</text>"##,
            short(x),
            short(y),
            crate::render::palette::hex(k),
            short(font / 20.0),
            short(x + 1.5 * font),
            short(y + 0.85 * font),
            if v == outside { " (outside)" } else { "" },
            f = short(font),
        )?;
    }
    writeln!(w, "</g>")
}

fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

fn path_data(points: impl Iterator<Item = DVec2>, closed: bool) -> String {
    let mut d = String::new();
    for (k, p) in points.enumerate() {
        d.push_str(if k == 0 { "M" } else { " L" });
        d.push_str(&format!("{} {}", num(p.x), num(p.y)));
    }
    if closed {
        d.push_str(" Z");
    }
    d
}

/// Writes iso-contours: `image` gives the size and, for slices, the physical
/// mapping; `meta` is merged into the JSON output (parameters, statistics).
pub fn write_contours(
    path: &Path,
    contours: &Contours,
    image: &Image2d,
    meta: &serde_json::Value,
) -> Result<()> {
    match ContourFormat::of(path)? {
        ContourFormat::Svg => atomic_write_with(path, |w| {
            svg_header(
                w,
                contours.width,
                contours.height,
                &format!("DICONEX contours of {}", image.path.display()),
            )?;
            for (k, c) in contours.contours.iter().enumerate() {
                let hole = c.is_hole();
                writeln!(
                    w,
                    r#"<path id="c{k}" class="{}" d="{}" fill="none" stroke="{}" stroke-width="0.12" stroke-linejoin="round"/>"#,
                    if hole { "hole" } else { "shape" },
                    path_data(c.points.iter().copied(), true),
                    if hole { "#d62728" } else { "#1f77b4" }
                )?;
            }
            writeln!(w, "</svg>")
        }),
        ContourFormat::Csv => atomic_write_with(path, |w| {
            let phys = image.slice.is_some();
            write!(w, "contour,hole,point,x,y")?;
            if phys {
                write!(w, ",x_mm,y_mm,z_mm")?;
            }
            writeln!(w)?;
            for (k, c) in contours.contours.iter().enumerate() {
                let hole = c.is_hole() as u8;
                for (i, p) in c.points.iter().enumerate() {
                    write!(w, "{k},{hole},{i},{},{}", num(p.x), num(p.y))?;
                    if let Some(q) = image.physical(*p) {
                        write!(w, ",{},{},{}", num(q.x), num(q.y), num(q.z))?;
                    }
                    writeln!(w)?;
                }
            }
            Ok(())
        }),
        ContourFormat::Json => {
            let list: Vec<serde_json::Value> = contours
                .contours
                .iter()
                .map(|c| {
                    let mut o = serde_json::json!({
                        "hole": c.is_hole(),
                        "signed_area": c.signed_area(),
                        "points": c.points.iter().map(|p| [p.x, p.y]).collect::<Vec<_>>(),
                    });
                    if image.slice.is_some() {
                        o["points_mm"] = serde_json::json!(
                            c.points
                                .iter()
                                .filter_map(|&p| image.physical(p))
                                .map(|q| [q.x, q.y, q.z])
                                .collect::<Vec<_>>()
                        );
                    }
                    o
                })
                .collect();
            let mut j = meta.clone();
            j["contours"] = serde_json::Value::Array(list);
            write_json(path, &j)
        }
    }
}

/// Writes label contours (see [`write_contours`]).
pub fn write_label_contours(
    path: &Path,
    lc: &LabelContours,
    image: &Image2d,
    meta: &serde_json::Value,
) -> Result<()> {
    match ContourFormat::of(path)? {
        ContourFormat::Svg => {
            let labels = image.labels()?;
            if labels.len() != lc.width * lc.height {
                return Err(Error::invalid(format!(
                    "{} labels for contours of {} × {} pixels",
                    labels.len(),
                    lc.width,
                    lc.height
                )));
            }
            let values = label_colours(&labels, lc.outside);
            let font = legend_font(lc.width, lc.height);
            let legend = (
                legend_width(&values, font),
                font * (0.5 + 1.5 * values.len() as f64),
            );
            atomic_write_with(path, |w| {
                svg_header_with_legend(
                    w,
                    lc.width,
                    lc.height,
                    legend,
                    &format!("label contours of {}", image.path.display()),
                )?;
                write_label_fills(w, &labels, lc.width, &values)?;
                for (k, pl) in lc.polylines.iter().enumerate() {
                    writeln!(
                        w,
                        r##"<path id="p{k}" data-labels="{} {}" d="{}" fill="none" stroke="#222" stroke-width="0.12" stroke-linejoin="round"/>"##,
                        pl.labels[0],
                        pl.labels[1],
                        path_data(pl.points.iter().map(|&i| lc.points[i as usize]), pl.closed),
                    )?;
                }
                for p in &lc.points[lc.first_junction..] {
                    writeln!(
                        w,
                        r#"<circle class="junction" cx="{}" cy="{}" r="0.15" fill="black"/>"#,
                        num(p.x),
                        num(p.y)
                    )?;
                }
                write_legend(w, lc.width, &values, lc.outside, font)?;
                writeln!(w, "</svg>")
            })
        }
        ContourFormat::Csv => atomic_write_with(path, |w| {
            let phys = image.slice.is_some();
            write!(
                w,
                "polyline,label_a,label_b,closed,point,point_id,junction,x,y"
            )?;
            if phys {
                write!(w, ",x_mm,y_mm,z_mm")?;
            }
            writeln!(w)?;
            for (k, pl) in lc.polylines.iter().enumerate() {
                for (i, &id) in pl.points.iter().enumerate() {
                    let p = lc.points[id as usize];
                    write!(
                        w,
                        "{k},{},{},{},{i},{id},{},{},{}",
                        pl.labels[0],
                        pl.labels[1],
                        pl.closed as u8,
                        lc.is_junction(id) as u8,
                        num(p.x),
                        num(p.y)
                    )?;
                    if let Some(q) = image.physical(p) {
                        write!(w, ",{},{},{}", num(q.x), num(q.y), num(q.z))?;
                    }
                    writeln!(w)?;
                }
            }
            Ok(())
        }),
        ContourFormat::Json => {
            let mut j = meta.clone();
            j["points"] =
                serde_json::json!(lc.points.iter().map(|p| [p.x, p.y]).collect::<Vec<_>>());
            if image.slice.is_some() {
                j["points_mm"] = serde_json::json!(
                    lc.points
                        .iter()
                        .filter_map(|&p| image.physical(p))
                        .map(|q| [q.x, q.y, q.z])
                        .collect::<Vec<_>>()
                );
            }
            j["first_junction"] = serde_json::json!(lc.first_junction);
            j["polylines"] = serde_json::json!(
                lc.polylines
                    .iter()
                    .map(|pl| serde_json::json!({
                        "labels": pl.labels,
                        "closed": pl.closed,
                        "points": pl.points,
                    }))
                    .collect::<Vec<_>>()
            );
            write_json(path, &j)
        }
    }
}

fn write_json(path: &Path, j: &serde_json::Value) -> Result<()> {
    atomic_write_with(path, |w| {
        serde_json::to_writer(&mut *w, j).map_err(std::io::Error::other)?;
        writeln!(w)
    })
}
