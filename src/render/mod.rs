//! Pictures of septa's results without a display or a GPU: `preview.png`, a
//! software rendering of an [`InterfaceMesh`], and the [`palette`] that the
//! preview and the contour SVGs share.
//!
//! [`render_preview`] draws the mesh in a few orthographic views laid out two
//! per row (by default [`DEFAULT_VIEWS`]: an oblique view of the whole mesh,
//! then views from the front, the left and below with the near half cut away
//! at the centre of the bounding box, so the inner patches show). Each view
//! is rasterised on the CPU with a z-buffer: every triangle in its patch's
//! palette colour, flat Lambert shading (two-sided: a patch is seen from both
//! labels), darker outlines where the depth jumps, and the junction curves as
//! dark lines over the visible surface. The views share one scale, fitted to
//! the mesh's bounding box. Views render in parallel; the picture does not
//! depend on the thread count. All work is over flat arrays: no allocation
//! per triangle or pixel.
//!
//! [`write_preview_png`] encodes it with the `png` crate and writes it
//! atomically (a temporary file, then a rename), as every septa output.
//!
//! Coordinates are the mesh's (LPS mm, as the pipeline makes it): x toward
//! the patient's left, y posterior, z superior. The front view looks from
//! anterior with the patient's left on the right of the picture, the left
//! view from the patient's left, the view from below (radiological axial)
//! with anterior up.

pub mod palette;

use std::path::Path;

use glam::DVec3;
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::mesh::InterfaceMesh;

/// Colour of pixels that show no triangle.
pub const BACKGROUND: [u8; 3] = [255, 255, 255];
/// Colour of the junction curves.
pub const JUNCTION_COLOR: [u8; 3] = [25, 25, 25];
/// Colour of the lines between the views.
const SEPARATOR: [u8; 3] = [200, 200, 200];

/// Where a view looks from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Direction {
    /// From anterior, left and above.
    Oblique,
    /// From anterior (coronal), superior up.
    Front,
    /// From the patient's left (sagittal), superior up.
    Left,
    /// From below (axial, radiological), anterior up.
    Below,
}

/// One view of the preview.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct View {
    pub direction: Direction,
    /// Cut away the half nearer the viewer (at the bounding box's centre).
    pub cut: bool,
}

/// The views of `preview.png`: the whole mesh obliquely, then three cut
/// orthogonal views.
pub const DEFAULT_VIEWS: [View; 4] = [
    View {
        direction: Direction::Oblique,
        cut: false,
    },
    View {
        direction: Direction::Front,
        cut: true,
    },
    View {
        direction: Direction::Left,
        cut: true,
    },
    View {
        direction: Direction::Below,
        cut: true,
    },
];

/// Largest side of one view, pixels.
pub const MAX_VIEW_SIZE: usize = 4096;

/// Options of [`render_preview`].
#[derive(Clone, Debug, PartialEq)]
pub struct PreviewOptions {
    /// Side of each (square) view in pixels, 16 to [`MAX_VIEW_SIZE`].
    pub view_size: usize,
    /// The views, two per row (1 to 16).
    pub views: Vec<View>,
    /// Lambert shading and outlines; off, every visible triangle has exactly
    /// its patch's palette colour (for tests and masks).
    pub shading: bool,
    /// Draw the junction curves.
    pub junctions: bool,
}

impl Default for PreviewOptions {
    fn default() -> Self {
        PreviewOptions {
            view_size: 400,
            views: DEFAULT_VIEWS.to_vec(),
            shading: true,
            junctions: true,
        }
    }
}

impl PreviewOptions {
    /// An error if the options cannot be used.
    pub fn check(&self) -> Result<()> {
        if !(16..=MAX_VIEW_SIZE).contains(&self.view_size) {
            return Err(Error::invalid(format!(
                "preview view size {} px: must be 16 to {MAX_VIEW_SIZE}",
                self.view_size
            )));
        }
        if !(1..=16).contains(&self.views.len()) {
            return Err(Error::invalid(format!(
                "{} preview views: must be 1 to 16",
                self.views.len()
            )));
        }
        Ok(())
    }
}

/// An RGB image, 8 bits per channel, rows from the top.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RgbImage {
    pub width: usize,
    pub height: usize,
    /// `3 · width · height` bytes, x fastest.
    pub rgb: Vec<u8>,
}

impl RgbImage {
    /// The colour of pixel `(x, y)`.
    pub fn pixel(&self, x: usize, y: usize) -> [u8; 3] {
        let k = 3 * (x + self.width * y);
        [self.rgb[k], self.rgb[k + 1], self.rgb[k + 2]]
    }

    /// The image as PNG bytes.
    pub fn to_png(&self) -> Result<Vec<u8>> {
        crate::io::image2d::encode_png(self.width, self.height, 3, false, &self.rgb)
    }
}

/// An orthographic camera: screen right, screen up, and the viewing
/// direction (into the picture), orthonormal, `right = forward × up`.
#[derive(Clone, Copy, Debug)]
struct Camera {
    right: DVec3,
    up: DVec3,
    forward: DVec3,
}

impl Camera {
    fn new(d: Direction) -> Self {
        let (forward, up_hint) = match d {
            // LPS: +x left, +y posterior, +z superior; the eye at anterior-left-superior
            Direction::Oblique => (-DVec3::new(0.75, -1.0, 0.6), DVec3::Z),
            Direction::Front => (DVec3::Y, DVec3::Z),
            Direction::Left => (-DVec3::X, DVec3::Z),
            Direction::Below => (DVec3::Z, -DVec3::Y),
        };
        let forward = forward.normalize();
        let right = forward.cross(up_hint).normalize();
        let up = right.cross(forward);
        Camera { right, up, forward }
    }
}

/// The bounding box of the finite positions, if there is one.
fn bounds(positions: &[DVec3]) -> Option<(DVec3, DVec3)> {
    let mut b: Option<(DVec3, DVec3)> = None;
    for p in positions.iter().filter(|p| p.is_finite()) {
        b = Some(match b {
            None => (*p, *p),
            Some((lo, hi)) => (lo.min(*p), hi.max(*p)),
        });
    }
    b
}

/// Renders the views of `mesh` into one picture (see the module docs):
/// `2 · view_size` wide (one view: `view_size`), rows of two views. A mesh
/// without triangles gives the background; vertices that are not finite and
/// triangles with bad vertex ids are skipped.
pub fn render_preview(mesh: &InterfaceMesh, opts: &PreviewOptions) -> Result<RgbImage> {
    opts.check()?;
    let size = opts.view_size;
    let cols = opts.views.len().min(2);
    let rows = opts.views.len().div_ceil(cols);
    let cameras: Vec<Camera> = opts
        .views
        .iter()
        .map(|v| Camera::new(v.direction))
        .collect();
    let views: Vec<Vec<u8>> = match bounds(&mesh.positions) {
        None => vec![BACKGROUND.repeat(size * size); opts.views.len()],
        Some((lo, hi)) => {
            let centre = (lo + hi) / 2.0;
            // one scale for all views: the box's projected extent fits with a margin
            let corners: Vec<DVec3> = (0..8)
                .map(|k| {
                    DVec3::new(
                        if k & 1 == 0 { lo.x } else { hi.x },
                        if k & 2 == 0 { lo.y } else { hi.y },
                        if k & 4 == 0 { lo.z } else { hi.z },
                    ) - centre
                })
                .collect();
            let extent = cameras
                .iter()
                .map(|c| {
                    let (mut w, mut h) = (0.0f64, 0.0f64);
                    for &p in &corners {
                        w = w.max(2.0 * c.right.dot(p).abs());
                        h = h.max(2.0 * c.up.dot(p).abs());
                    }
                    w.max(h)
                })
                .fold(0.0f64, f64::max);
            let scale = if extent > 0.0 && extent.is_finite() {
                0.92 * size as f64 / extent
            } else {
                1.0
            };
            opts.views
                .par_iter()
                .zip(&cameras)
                .map(|(v, cam)| render_view(mesh, cam, centre, scale, size, v.cut, opts))
                .collect()
        }
    };
    let (width, height) = (cols * size, rows * size);
    let mut rgb = BACKGROUND.repeat(width * height);
    for (k, view) in views.iter().enumerate() {
        let (x0, y0) = ((k % cols) * size, (k / cols) * size);
        for j in 0..size {
            let dst = 3 * (x0 + width * (y0 + j));
            rgb[dst..dst + 3 * size].copy_from_slice(&view[3 * size * j..3 * size * (j + 1)]);
        }
    }
    for c in 1..cols {
        for y in 0..height {
            let k = 3 * (c * size + width * y);
            rgb[k..k + 3].copy_from_slice(&SEPARATOR);
        }
    }
    for r in 1..rows {
        let k = 3 * width * (r * size);
        for x in 0..width {
            rgb[k + 3 * x..k + 3 * x + 3].copy_from_slice(&SEPARATOR);
        }
    }
    Ok(RgbImage { width, height, rgb })
}

/// Renders one view: `size × size` RGB bytes.
fn render_view(
    mesh: &InterfaceMesh,
    cam: &Camera,
    centre: DVec3,
    scale: f64,
    size: usize,
    cut: bool,
    opts: &PreviewOptions,
) -> Vec<u8> {
    let half = size as f64 / 2.0;
    // screen x, screen y (rows down), depth in mm from the centre (into the picture)
    let projected: Vec<[f32; 3]> = mesh
        .positions
        .iter()
        .map(|&p| {
            let q = p - centre;
            [
                (half + scale * cam.right.dot(q)) as f32,
                (half - scale * cam.up.dot(q)) as f32,
                cam.forward.dot(q) as f32,
            ]
        })
        .collect();
    let n = projected.len();
    let zcut = if cut { 0.0f32 } else { f32::NEG_INFINITY };
    let mut depth = vec![f32::INFINITY; size * size];
    let mut ids = vec![u32::MAX; size * size];
    let max = (size - 1) as f32;
    for (t, tri) in mesh.triangles.iter().enumerate() {
        if tri.iter().any(|&v| v as usize >= n) {
            continue;
        }
        let [a, b, c] = tri.map(|v| projected[v as usize]);
        if a[2] < zcut && b[2] < zcut && c[2] < zcut {
            continue;
        }
        let area = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
        // also skips triangles with a vertex that is not finite
        if !(area.abs() > 1e-12) {
            continue;
        }
        let inv = 1.0 / area;
        // pixel i covers centre i + 0.5
        let lo_x = (a[0].min(b[0]).min(c[0]) - 0.5).ceil().max(0.0);
        let hi_x = (a[0].max(b[0]).max(c[0]) - 0.5).floor().min(max);
        let lo_y = (a[1].min(b[1]).min(c[1]) - 0.5).ceil().max(0.0);
        let hi_y = (a[1].max(b[1]).max(c[1]) - 0.5).floor().min(max);
        if !(lo_x <= hi_x && lo_y <= hi_y) {
            continue;
        }
        let (i0, i1, j0, j1) = (lo_x as usize, hi_x as usize, lo_y as usize, hi_y as usize);
        for j in j0..=j1 {
            let y = j as f32 + 0.5;
            let row = j * size;
            for i in i0..=i1 {
                let x = i as f32 + 0.5;
                let w0 = ((c[0] - b[0]) * (y - b[1]) - (c[1] - b[1]) * (x - b[0])) * inv;
                let w1 = ((a[0] - c[0]) * (y - c[1]) - (a[1] - c[1]) * (x - c[0])) * inv;
                let w2 = 1.0 - w0 - w1;
                if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                    continue;
                }
                let z = w0 * a[2] + w1 * b[2] + w2 * c[2];
                let k = row + i;
                if z >= zcut && z < depth[k] {
                    depth[k] = z;
                    ids[k] = t as u32;
                }
            }
        }
    }

    // shading: per pixel from its triangle (cached along runs of one triangle)
    let light = (-0.35 * cam.right + 0.5 * cam.up - 0.8 * cam.forward).normalize();
    let mut rgb = BACKGROUND.repeat(size * size);
    let mut last = (u32::MAX, BACKGROUND);
    for (k, &t) in ids.iter().enumerate() {
        if t == u32::MAX {
            continue;
        }
        if t != last.0 {
            let patch = mesh.triangle_patch.get(t as usize).copied().unwrap_or(0);
            let base = palette::color(patch as usize);
            let colour = if opts.shading {
                let [a, b, c] = mesh.triangles[t as usize].map(|v| mesh.positions[v as usize]);
                let nrm = (b - a).cross(c - a).normalize_or_zero();
                let i = 0.3 + 0.7 * nrm.dot(light).abs();
                base.map(|x| (x as f64 * i).round().min(255.0) as u8)
            } else {
                base
            };
            last = (t, colour);
        }
        rgb[3 * k..3 * k + 3].copy_from_slice(&last.1);
    }

    // outlines where the depth jumps by more than a few pixels' worth
    if opts.shading {
        let jump = (4.0 / scale) as f32;
        for j in 0..size {
            for i in 0..size {
                let k = j * size + i;
                let z = depth[k];
                let right = if i + 1 < size { depth[k + 1] } else { z };
                let down = if j + 1 < size { depth[k + size] } else { z };
                let edge = |o: f32| (z.is_finite() || o.is_finite()) && !((z - o).abs() <= jump);
                if edge(right) || edge(down) {
                    // the nearer side of the step gets the line
                    let o = if edge(right) { k + 1 } else { k + size };
                    let near = if depth[o] < z { o } else { k };
                    for x in &mut rgb[3 * near..3 * near + 3] {
                        *x = (*x as u32 * 45 / 100) as u8;
                    }
                }
            }
        }
    }

    if opts.junctions {
        let eps = (3.0 / scale) as f32;
        for curve in &mesh.junctions {
            let vs = &curve.vertices;
            let segments = vs.len().saturating_sub(1) + (curve.closed && vs.len() > 2) as usize;
            for s in 0..segments {
                let (p, q) = (vs[s] as usize, vs[(s + 1) % vs.len()] as usize);
                let (Some(p), Some(q)) = (projected.get(p), projected.get(q)) else {
                    continue;
                };
                if !(p.iter().chain(q).all(|x| x.is_finite())) {
                    continue;
                }
                let steps = (q[0] - p[0]).abs().max((q[1] - p[1]).abs()).ceil().max(1.0) as usize;
                for s in 0..=steps {
                    let f = s as f32 / steps as f32;
                    let x = p[0] + f * (q[0] - p[0]);
                    let y = p[1] + f * (q[1] - p[1]);
                    let z = p[2] + f * (q[2] - p[2]);
                    if z < zcut {
                        continue;
                    }
                    // a 2 × 2 block around the point
                    let (x0, y0) = ((x - 1.0).round(), (y - 1.0).round());
                    for (dx, dy) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)] {
                        let (xi, yi) = (x0 + dx, y0 + dy);
                        if !(xi >= 0.0 && yi >= 0.0 && xi <= max && yi <= max) {
                            continue;
                        }
                        let k = yi as usize * size + xi as usize;
                        if z <= depth[k] + eps {
                            rgb[3 * k..3 * k + 3].copy_from_slice(&JUNCTION_COLOR);
                        }
                    }
                }
            }
        }
    }
    rgb
}

/// Renders `mesh` ([`render_preview`]) and writes it to `path` as a PNG,
/// atomically (a temporary file beside it, then a rename).
pub fn write_preview_png(path: &Path, mesh: &InterfaceMesh, opts: &PreviewOptions) -> Result<()> {
    let png = render_preview(mesh, opts)?.to_png()?;
    crate::io::atomic_write(path, &png)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::{Config, RemeshOptions};
    use crate::pipeline::{PipelineOptions, run};

    /// The phantom of `size³` voxels, as extracted (not remeshed).
    fn phantom(size: usize) -> InterfaceMesh {
        phantom_with_noise(size, 0.0)
    }

    fn phantom_with_noise(size: usize, noise: f64) -> InterfaceMesh {
        let volume = crate::phantom::heart(&crate::phantom::PhantomParams {
            size,
            noise,
            ..Default::default()
        })
        .unwrap();
        let options = PipelineOptions {
            remesh: RemeshOptions {
                enabled: Some(false),
                ..Default::default()
            },
            ..Default::default()
        };
        run(volume, &Config::default(), &options, &mut |_| {})
            .unwrap()
            .mesh
    }

    fn flat() -> PreviewOptions {
        PreviewOptions {
            view_size: 120,
            shading: false,
            junctions: false,
            ..Default::default()
        }
    }

    #[test]
    fn the_phantom_shows_its_patches_in_their_colours_on_the_background() {
        let mesh = phantom(16);
        assert!(mesh.patches.len() >= 10);
        let img = render_preview(&mesh, &flat()).unwrap();
        assert_eq!((img.width, img.height), (240, 240));
        // every pixel is the background, a separator or a patch's colour
        let colours: Vec<[u8; 3]> = (0..mesh.patches.len()).map(palette::color).collect();
        let mut seen = vec![0usize; colours.len()];
        let mut background = 0;
        for y in 0..img.height {
            for x in 0..img.width {
                let c = img.pixel(x, y);
                if c == BACKGROUND {
                    background += 1;
                } else if let Some(p) = colours.iter().position(|&q| q == c) {
                    seen[p] += 1;
                } else {
                    assert!(x == 120 || y == 120, "({x}, {y}) has {c:?}");
                }
            }
        }
        // the outer surface in the oblique view, inner patches in the cut ones
        let shown = seen.iter().filter(|&&n| n > 0).count();
        assert!(
            shown >= 8,
            "{shown} of {} patches shown",
            mesh.patches.len()
        );
        let covered = img.width * img.height - background;
        assert!(covered > img.width * img.height / 5, "{covered} pixels");
        // the corners of every view are background (the mesh fits with a margin)
        for (x0, y0) in [(0, 0), (120, 0), (0, 120), (120, 120)] {
            for (dx, dy) in [(1, 1), (118, 1), (1, 118), (118, 118)] {
                assert_eq!(img.pixel(x0 + dx, y0 + dy), BACKGROUND);
            }
        }
        // the oblique view shows only the outer surface: patches with label 0
        // (the outside); the cut views show patches between two tissues
        let outer = |p: usize| mesh.patches[p].labels[0] == 0;
        for y in 0..120 {
            for x in 0..120 {
                if let Some(p) = colours.iter().position(|&q| q == img.pixel(x, y)) {
                    assert!(outer(p), "oblique view shows inner patch {p}");
                }
            }
        }
        let inner = (120..240)
            .flat_map(|x| (0..120).map(move |y| (x, y)))
            .filter_map(|(x, y)| colours.iter().position(|&q| q == img.pixel(x, y)))
            .filter(|&p| !outer(p))
            .count();
        assert!(
            inner > 100,
            "{inner} pixels of inner patches in the front view"
        );
    }

    #[test]
    fn the_preview_is_deterministic_and_decodes_as_png() {
        let mesh = phantom(16);
        let opts = PreviewOptions {
            view_size: 100,
            ..Default::default()
        };
        let a = render_preview(&mesh, &opts).unwrap();
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        let b = one.install(|| render_preview(&mesh, &opts)).unwrap();
        assert_eq!(a, b);
        // shading makes many shades; junction curves are drawn
        let junction = (0..a.height)
            .flat_map(|y| (0..a.width).map(move |x| (x, y)))
            .filter(|&(x, y)| a.pixel(x, y) == JUNCTION_COLOR)
            .count();
        assert!(junction > 50, "{junction} junction pixels");
        let no_curves = render_preview(
            &mesh,
            &PreviewOptions {
                junctions: false,
                ..opts.clone()
            },
        )
        .unwrap();
        assert_ne!(a, no_curves);
        let png = a.to_png().unwrap();
        let mut reader = png::Decoder::new(std::io::Cursor::new(&png))
            .read_info()
            .unwrap();
        let mut buf = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut buf).unwrap();
        assert_eq!((info.width, info.height), (200, 200));
        assert_eq!(info.color_type, png::ColorType::Rgb);
        assert_eq!(buf, a.rgb);
    }

    #[test]
    fn bad_meshes_and_options_do_not_panic() {
        let empty = InterfaceMesh::default();
        let img = render_preview(&empty, &flat()).unwrap();
        assert!(img.rgb.chunks(3).all(|c| c == BACKGROUND || c == SEPARATOR));
        let mut mesh = phantom(8);
        mesh.positions[0] = DVec3::NAN;
        mesh.triangles.push([0, 1, u32::MAX]);
        mesh.triangle_patch.pop();
        mesh.junctions.push(crate::mesh::JunctionCurve {
            vertices: vec![0, 1, 7_000_000],
            closed: true,
            labels: vec![],
        });
        render_preview(&mesh, &PreviewOptions::default()).unwrap();
        for bad in [0, 8, 5000] {
            let opts = PreviewOptions {
                view_size: bad,
                ..Default::default()
            };
            assert!(render_preview(&mesh, &opts).is_err());
        }
        let opts = PreviewOptions {
            views: vec![],
            ..Default::default()
        };
        assert!(render_preview(&mesh, &opts).is_err());
        // one view: one view wide
        let opts = PreviewOptions {
            views: vec![DEFAULT_VIEWS[1]],
            ..flat()
        };
        assert_eq!(render_preview(&mesh, &opts).unwrap().width, 120);
    }

    /// Time of the default preview of a ~1M-triangle mesh (the 96³ phantom
    /// with noise, not remeshed): `cargo test --lib -- --ignored preview_timing
    /// --nocapture`, with `RAYON_NUM_THREADS=1` for one core.
    #[test]
    #[ignore]
    fn preview_timing() {
        let mesh = phantom_with_noise(96, 0.2);
        let start = std::time::Instant::now();
        let img = render_preview(&mesh, &PreviewOptions::default()).unwrap();
        let render = start.elapsed();
        let png = img.to_png().unwrap();
        println!(
            "{} triangles: render {:.3} s, PNG encode {:.3} s ({} bytes)",
            mesh.triangle_count(),
            render.as_secs_f64(),
            (start.elapsed() - render).as_secs_f64(),
            png.len()
        );
    }
}
