//! A synthetic heart: a label volume with the topology of a whole-heart
//! segmentation, for tests, benchmarks and demonstrations.
//!
//! # Anatomy
//!
//! The phantom is built from analytic shapes (ellipsoids, half-spaces and tubes
//! around line segments and circular arcs), evaluated per voxel in *normalized*
//! coordinates: the volume spans `[-1, 1]` along every axis whatever its size, so
//! the heart scales with the grid and any size from 4 up works. The spacing only
//! sets the physical geometry (an anisotropic spacing stretches the heart); the
//! volume is centred at (0, 0, 0) mm with identity direction. The shapes
//! live in a heart frame (`z` from apex to base) that is tilted so that the apex
//! points to the patient's left, anterior and inferior, as in a chest CT (LPS
//! axes: `x` toward Left, `y` toward Posterior, `z` toward Superior).
//!
//! * **Ventricles** – the left ventricle (`lv_blood`) is a half ellipsoid, open
//!   at the base, inside a thick ellipsoidal `myocardium`. The right ventricle
//!   (`rv_blood`) is a crescent wrapped around the right and anterior side of the
//!   LV: a larger ellipsoid minus the LV myocardium, so the interventricular
//!   septum is LV myocardium, with a thin free wall of its own. A myocardial
//!   plate closes both ventricles at the base.
//! * **Valves** – four holes in the basal plate: mitral (LV ↔ LA) and tricuspid
//!   (RV ↔ RA) open into the atria; aortic and pulmonary open into the great
//!   arteries. Their rims are curves where three labels meet.
//! * **Atria** – `la_blood` and `ra_blood` are ellipsoids above the base,
//!   without a labelled wall (as in most CT segmentations), split by a thin
//!   myocardial interatrial septum.
//! * **Great arteries** – `aorta` and `pulmonary_artery` are the *walls* of two
//!   tubes, thin on purpose: 1.42 voxels up to size 128 (just over √2, so
//!   that lumen and outside never meet, not even along a voxel edge), growing
//!   to 3 voxels at size 256 (below size 22 the tubes are solid wall). The
//!   lumen holds the blood of the ventricle that ejects into it (`lv_blood` in
//!   the aorta, `rv_blood` in the pulmonary artery). The aorta rises from the
//!   LV, arches backwards and descends behind the heart, straight down and out
//!   of the bottom of the volume; the pulmonary trunk rises from the RV, crosses
//!   in front of the ascending aorta and splits into left and right branches,
//!   the right one passing under the arch. The arteries touch each other and
//!   the atria, so the phantom has triple junctions (three labels along a curve)
//!   and quadruple junctions (four labels at a point).
//!
//! Shape sizes are fractions of the volume; only wall thicknesses have a floor
//! in voxels, so that walls stay closed at small sizes. Rasterization of thin
//! shapes leaves a few voxels without a face neighbour of their own label;
//! these take the most common label of their face neighbours. The clean phantom
//! still has a few critical configurations where thin walls and touching
//! shapes meet (about 70 critical edges at size 64, 300 at size 256).
//!
//! LV and RV blood never share a voxel face in the clean phantom: myocardium
//! (or two arterial walls) always lies between them.
//!
//! # Noise
//!
//! With [`PhantomParams::noise`] `= p`, every voxel that has a 6-neighbour of
//! another label takes, with probability `p`, the label of one of its
//! 26-neighbours that differs from it, chosen uniformly. The noise pass reads
//! the clean volume and writes a new one, so the result does not depend on the
//! order of visits; its random numbers come from a counter-based hash of the
//! seed and the voxel index (SplitMix64), so the result is the same for every
//! number of threads. Noise turns smooth interfaces into ragged ones with many
//! critical configurations: two voxels of one label touching only along an edge
//! or at a corner.

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::volume::{Dims, Geometry, LabelId, LabelVolume};

/// The labels of the phantom: value and name (the names of `configs/heart.toml`).
pub const LABELS: &[(i64, &str)] = &[
    (0, "background"),
    (1, "lv_blood"),
    (2, "rv_blood"),
    (3, "la_blood"),
    (4, "ra_blood"),
    (5, "myocardium"),
    (6, "aorta"),
    (7, "pulmonary_artery"),
];

const BG: LabelId = 0;
const LV: LabelId = 1;
const RV: LabelId = 2;
const LA: LabelId = 3;
const RA: LabelId = 4;
const MYO: LabelId = 5;
const AO: LabelId = 6;
const PA: LabelId = 7;

/// Parameters of [`heart`].
#[derive(Clone, Debug, PartialEq)]
pub struct PhantomParams {
    /// Voxels along each axis (the grid is `size³`), 4 to 2048; sizes above
    /// 1625 also exceed [`MAX_VOXELS`](crate::volume::MAX_VOXELS).
    pub size: usize,
    /// Voxel spacing in mm along x, y, z (positive, finite).
    pub spacing: [f64; 3],
    /// Probability of flipping a voxel next to an interface, in `[0, 1]`.
    pub noise: f64,
    /// Seed of the noise.
    pub seed: u64,
}

impl Default for PhantomParams {
    /// Size 64, 1 mm spacing, no noise, seed 1.
    fn default() -> Self {
        PhantomParams {
            size: 64,
            spacing: [1.0; 3],
            noise: 0.0,
            seed: 1,
        }
    }
}

/// Generates the heart phantom (see the [module documentation](self)).
///
/// The volume is `size³` voxels, centred at (0, 0, 0) mm with identity
/// direction; its value table holds the values of [`LABELS`] that occur (all of
/// them for sizes ≥ 16).
///
/// ```
/// use septa::phantom::{heart, PhantomParams, LABELS};
/// let v = heart(&PhantomParams { size: 24, ..Default::default() }).unwrap();
/// assert_eq!(v.dims().to_array(), [24, 24, 24]);
/// assert_eq!(v.label_count(), LABELS.len());
/// assert_eq!(v.geometry().origin(), [-11.5, -11.5, -11.5]);
/// assert!(heart(&PhantomParams { size: 2, ..Default::default() }).is_err());
/// ```
pub fn heart(params: &PhantomParams) -> Result<LabelVolume> {
    validate(params)?;
    let n = params.size;
    let dims = Dims::new(n, n, n)?;
    let origin = params.spacing.map(|s| -0.5 * (n as f64 - 1.0) * s);
    let geometry = Geometry::new(params.spacing, origin, Geometry::IDENTITY_DIRECTION)?;
    let mut ids = despeckle(&rasterize(&Heart::new(n), dims), dims);
    if params.noise > 0.0 {
        ids = add_noise(&ids, dims, params.noise, params.seed);
    }
    compact(dims, ids, geometry)
}

fn validate(p: &PhantomParams) -> Result<()> {
    if !(4..=2048).contains(&p.size) {
        return Err(Error::invalid(format!(
            "phantom size {} is out of range: it must be 4 to 2048 voxels",
            p.size
        )));
    }
    if let Some(s) = p.spacing.iter().find(|s| !(s.is_finite() && **s > 0.0)) {
        return Err(Error::invalid(format!(
            "phantom spacing {s} mm: it must be a positive finite number"
        )));
    }
    if !(0.0..=1.0).contains(&p.noise) {
        return Err(Error::invalid(format!(
            "phantom noise {}: it must be a probability in [0, 1]",
            p.noise
        )));
    }
    Ok(())
}

/// A volume whose value table holds only the labels that occur.
fn compact(dims: Dims, mut ids: Vec<LabelId>, geometry: Geometry) -> Result<LabelVolume> {
    let mut present = [false; LABELS.len()];
    for chunk in ids.chunks(1 << 16) {
        chunk.iter().for_each(|&i| present[i as usize] = true);
    }
    let mut remap = [0 as LabelId; LABELS.len()];
    let mut values = Vec::with_capacity(LABELS.len());
    for (i, &(value, _)) in LABELS.iter().enumerate() {
        if present[i] {
            remap[i] = values.len() as LabelId;
            values.push(value);
        }
    }
    if values.len() < LABELS.len() {
        ids.par_iter_mut().for_each(|i| *i = remap[*i as usize]);
    }
    LabelVolume::from_ids(dims, ids, values, geometry)
}

// ---------------------------------------------------------------------------
// Shapes

type V3 = [f64; 3];

fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn norm(a: V3) -> f64 {
    dot(a, a).sqrt()
}

fn unit(a: V3) -> V3 {
    let l = norm(a);
    [a[0] / l, a[1] / l, a[2] / l]
}

fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// An axis-aligned ellipsoid (in the heart frame).
#[derive(Clone, Copy)]
struct Ellipsoid {
    centre: V3,
    inv_radii: V3,
}

impl Ellipsoid {
    fn new(centre: V3, radii: V3) -> Self {
        Ellipsoid {
            centre,
            inv_radii: radii.map(|r| 1.0 / r),
        }
    }

    /// The same centre, every radius grown by `t`.
    fn grown(&self, t: f64) -> Self {
        Ellipsoid::new(self.centre, self.inv_radii.map(|ir| 1.0 / ir + t))
    }

    fn bounds(&self) -> (V3, V3) {
        let r = self.inv_radii.map(|ir| 1.0 / ir);
        (
            [0, 1, 2].map(|k| self.centre[k] - r[k]),
            [0, 1, 2].map(|k| self.centre[k] + r[k]),
        )
    }

    #[inline]
    fn contains(&self, q: V3) -> bool {
        let d = sub(q, self.centre);
        let s = [0, 1, 2].map(|k| d[k] * self.inv_radii[k]);
        dot(s, s) < 1.0
    }
}

/// A piece of a tube's centre line.
enum Piece {
    /// Segment `a → b`; with `open_start` the tube is cut flat at `a` instead
    /// of being capped by a half ball.
    Segment {
        a: V3,
        dir: V3,
        inv_len2: f64,
        open_start: bool,
    },
    /// Half circle of radius `r` around `centre`, from `centre + r·e1` over
    /// `centre + r·e2` to `centre − r·e1`.
    HalfCircle {
        centre: V3,
        r: f64,
        e1: V3,
        e2: V3,
        n: V3,
    },
}

impl Piece {
    fn segment(a: V3, b: V3, open_start: bool) -> Self {
        let dir = sub(b, a);
        Piece::Segment {
            a,
            dir,
            inv_len2: 1.0 / dot(dir, dir),
            open_start,
        }
    }

    /// The upward half circle from `a` to `b` (same height).
    fn arch(a: V3, b: V3) -> Self {
        let centre = [0, 1, 2].map(|k| 0.5 * (a[k] + b[k]));
        let e1 = sub(a, centre);
        let r = norm(e1);
        let e1 = unit(e1);
        let e2 = [0.0, 0.0, 1.0];
        Piece::HalfCircle {
            centre,
            r,
            e1,
            e2,
            n: cross(e1, e2),
        }
    }

    /// Bounding box of the centre line.
    fn bounds(&self) -> (V3, V3) {
        match *self {
            Piece::Segment { a, dir, .. } => {
                let b = [0, 1, 2].map(|k| a[k] + dir[k]);
                (
                    [0, 1, 2].map(|k| a[k].min(b[k])),
                    [0, 1, 2].map(|k| a[k].max(b[k])),
                )
            }
            Piece::HalfCircle {
                centre, r, e1, e2, ..
            } => {
                // centre + r·(cos θ·e1 + sin θ·e2), θ in [0, π].
                let lo = [0, 1, 2].map(|k| centre[k] - r * e1[k].abs() + r * e2[k].min(0.0));
                let hi = [0, 1, 2].map(|k| centre[k] + r * e1[k].abs() + r * e2[k].max(0.0));
                (lo, hi)
            }
        }
    }

    /// Distance from `q` to the piece (infinite past an open start or below the
    /// half circle's diameter, where the neighbouring pieces take over).
    #[inline]
    fn distance(&self, q: V3) -> f64 {
        match *self {
            Piece::Segment {
                a,
                dir,
                inv_len2,
                open_start,
            } => {
                let v = sub(q, a);
                let t = dot(v, dir) * inv_len2;
                if open_start && t < 0.0 {
                    return f64::INFINITY;
                }
                let t = t.clamp(0.0, 1.0);
                norm(sub(v, dir.map(|d| d * t)))
            }
            Piece::HalfCircle {
                centre,
                r,
                e1,
                e2,
                n,
            } => {
                let v = sub(q, centre);
                let (a1, a2, a3) = (dot(v, e1), dot(v, e2), dot(v, n));
                if a2 < 0.0 {
                    return f64::INFINITY;
                }
                let radial = (a1 * a1 + a2 * a2).sqrt() - r;
                (radial * radial + a3 * a3).sqrt()
            }
        }
    }
}

/// A hollow tube: wall of label `wall` between radii `r_in` and `r_out`,
/// lumen of label `lumen` inside.
struct Tube {
    pieces: Vec<Piece>,
    /// Bounding box of each piece, grown by `r_out` and a margin.
    boxes: Vec<(V3, V3)>,
    r_in: f64,
    r_out: f64,
    wall: LabelId,
    lumen: LabelId,
}

impl Tube {
    /// A tube of outer radius `r_out` with a wall `thickness` thick;
    /// [`Tube::distance`] is exact up to `r_out + margin`.
    fn new(
        pieces: Vec<Piece>,
        r_out: f64,
        thickness: f64,
        [wall, lumen]: [LabelId; 2],
        margin: f64,
    ) -> Self {
        let grow = r_out + margin;
        let boxes = pieces
            .iter()
            .map(|p| {
                let (lo, hi) = p.bounds();
                (lo.map(|c| c - grow), hi.map(|c| c + grow))
            })
            .collect();
        Tube {
            pieces,
            boxes,
            r_in: r_out - thickness,
            r_out,
            wall,
            lumen,
        }
    }

    /// Distance to the centre line; infinite far from it.
    #[inline]
    fn distance(&self, q: V3) -> f64 {
        let mut best = f64::INFINITY;
        for (piece, (lo, hi)) in self.pieces.iter().zip(&self.boxes) {
            if (0..3).all(|k| lo[k] <= q[k] && q[k] <= hi[k]) {
                best = best.min(piece.distance(q));
            }
        }
        best
    }

    /// Label of a point at distance `d` from the centre line (inside the tube).
    #[inline]
    fn label_at(&self, d: f64) -> LabelId {
        if d < self.r_in { self.lumen } else { self.wall }
    }
}

/// A valve: a vertical disc of radius `r` at `(x, y)` through the basal plate,
/// filled with `label`, continued upward to height `top` (for the atria).
struct Valve {
    x: f64,
    y: f64,
    r2: f64,
    top: f64,
    label: LabelId,
}

impl Valve {
    #[inline]
    fn contains(&self, q: V3) -> bool {
        let (dx, dy) = (q[0] - self.x, q[1] - self.y);
        dx * dx + dy * dy < self.r2
    }
}

// ---------------------------------------------------------------------------
// The heart

/// All shapes, in the heart frame. Its unit is `scale` normalized volume
/// units (the volume spans [-1, 1], one voxel is `2 / size`).
struct Heart {
    /// The heart frame's axes in volume coordinates (rows).
    rot: [V3; 3],
    /// Volume position of the heart-frame origin.
    shift: V3,
    /// Normalized volume units per heart-frame unit.
    scale: f64,
    /// Height of the ventricular base (top of the cavities) and of the plate top.
    base: f64,
    plate_top: f64,
    lv_cav: Ellipsoid,
    lv_myo: Ellipsoid,
    rv_cav: Ellipsoid,
    rv_myo: Ellipsoid,
    valves: [Valve; 4],
    la: Ellipsoid,
    ra: Ellipsoid,
    /// Interatrial septum: unit normal (toward the LA), a point on it, half width.
    septum: (V3, V3, f64),
    aorta: Tube,
    pa: Tube,
    /// Widest gap between the arteries that is filled with wall.
    bridge: f64,
    /// Heart-frame boxes covering every shape but the descending aorta.
    boxes: Vec<(V3, V3)>,
    /// The descending aorta in volume coordinates: x, y of its vertical axis,
    /// height of its top, radius with margin.
    descending: [f64; 4],
}

impl Heart {
    fn new(size: usize) -> Self {
        let scale = 1.45;
        let voxel = 2.0 / (size as f64 * scale);
        // Thin walls: about 1.4 voxels up to size 128 (just enough to keep both
        // sides from touching along voxel edges), then 3 voxels at size 256.
        let thin = voxel * (3.0 * size as f64 / 256.0).max(1.42);
        let thick = |t: f64| t.max(voxel);
        let base = 0.0;
        let plate_top = base + thick(0.06);
        let lv_cav = Ellipsoid::new([0.12, 0.06, 0.0], [0.23, 0.23, 0.46]);
        let rv_cav = Ellipsoid::new([-0.08, -0.12, 0.0], [0.38, 0.3, 0.42]);
        let (la_c, ra_c) = ([0.15, 0.18, 0.18], [-0.27, 0.1, 0.16]);
        let valve = |x: f64, y: f64, r: f64, top: f64, label| Valve {
            x,
            y,
            r2: r * r,
            top,
            label,
        };
        // Outer radii of the arteries are fixed (so that they touch at every
        // size); their walls grow inward.
        let (ao_r, pa_r) = (0.095, 0.09);
        let (ao_lumen, pa_lumen) = (ao_r - thin, pa_r - thin);
        let valves = [
            valve(0.18, 0.15, 0.075, la_c[2], LA),
            valve(-0.3, 0.0, 0.07, ra_c[2], RA),
            valve(0.0, 0.0, ao_lumen, plate_top, LV),
            valve(-0.2, -0.25, pa_lumen, plate_top, RV),
        ];
        let septum_n = unit([1.0, 0.3, 0.0]);
        let rot = rotation();
        let down = rot.map(|row| -row[2]);
        let (aorta, aorta_top) = aorta(plate_top, down, ao_r, thin, voxel);
        let mut heart = Heart {
            rot,
            shift: [0.0, -0.08, -0.15],
            scale,
            base,
            plate_top,
            lv_cav,
            lv_myo: lv_cav.grown(thick(0.1)),
            rv_cav,
            rv_myo: rv_cav.grown(thick(0.045)),
            valves,
            la: Ellipsoid::new(la_c, [0.24, 0.18, 0.24]),
            ra: Ellipsoid::new(ra_c, [0.22, 0.18, 0.2]),
            septum: (septum_n, [-0.07, 0.16, 0.0], 0.5 * thick(0.05)),
            aorta,
            pa: pulmonary_artery(plate_top, pa_r, thin, voxel),
            bridge: 0.5 * voxel,
            boxes: Vec::new(),
            descending: [0.0; 4],
        };
        heart.set_culling(aorta_top, voxel);
        heart
    }

    /// Fills `boxes` and `descending`, which let [`Heart::row_spans`] skip
    /// the background.
    fn set_culling(&mut self, aorta_top: V3, voxel: f64) {
        let below_plate = |(lo, mut hi): (V3, V3)| {
            hi[2] = hi[2].min(self.plate_top);
            (lo, hi)
        };
        let mut boxes = vec![
            below_plate(self.lv_myo.bounds()),
            below_plate(self.rv_myo.bounds()),
            self.la.bounds(),
            self.ra.bounds(),
        ];
        for v in &self.valves[..2] {
            let r = v.r2.sqrt();
            boxes.push(([v.x - r, v.y - r, self.base], [v.x + r, v.y + r, v.top]));
        }
        boxes.extend(self.pa.boxes.iter().copied());
        // Every piece of the aorta but the last, the descending one.
        boxes.extend(
            self.aorta.boxes[..self.aorta.boxes.len() - 1]
                .iter()
                .copied(),
        );
        self.boxes = boxes;
        let top = self.to_volume(aorta_top);
        let radius = (self.aorta.r_out + voxel) * self.scale;
        self.descending = [top[0], top[1], top[2], radius];
    }

    /// Normalized volume position of a heart-frame position.
    fn to_volume(&self, q: V3) -> V3 {
        [0, 1, 2].map(|k| {
            self.shift[k] + self.scale * (0..3).map(|a| q[a] * self.rot[a][k]).sum::<f64>()
        })
    }

    /// Intervals of volume x, on the row at volume `(y, z)`, outside of which
    /// everything is background: the rows's passages through the boxes of the
    /// shapes and through the descending aorta, sorted and merged.
    fn row_spans(&self, y: f64, z: f64, spans: &mut Vec<(f64, f64)>) {
        spans.clear();
        // Heart frame along the row: q(x) = q0 + x · dq.
        let q0 = self.to_heart([0.0, y, z]);
        let dq = self.rot.map(|axis| axis[0] / self.scale);
        spans.extend(self.boxes.iter().filter_map(|b| line_in_box(q0, dq, b)));
        let [ax, ay, top, r] = self.descending;
        let dy = y - ay;
        if z <= top && dy.abs() < r {
            let half = (r * r - dy * dy).sqrt();
            spans.push((ax - half, ax + half));
        }
        spans.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
        let mut merged = 0;
        for i in 0..spans.len() {
            if merged > 0 && spans[i].0 <= spans[merged - 1].1 {
                spans[merged - 1].1 = spans[merged - 1].1.max(spans[i].1);
            } else {
                spans[merged] = spans[i];
                merged += 1;
            }
        }
        spans.truncate(merged);
    }

    /// Heart-frame position of a normalized volume position.
    #[inline]
    fn to_heart(&self, p: V3) -> V3 {
        let d = sub(p, self.shift).map(|c| c / self.scale);
        self.rot.map(|axis| dot(axis, d))
    }

    /// The label at heart-frame position `q`.
    #[inline]
    fn label(&self, q: V3) -> LabelId {
        if let Some(l) = self.artery(q) {
            return l;
        }
        if q[2] < self.plate_top {
            if let Some(l) = self.ventricles(q) {
                return l;
            }
        }
        self.atria(q)
    }

    /// The great arteries. Where both claim a point it goes to the one it is
    /// deeper in; a gap of less than a voxel between them is bridged with wall,
    /// so that they touch at every size.
    #[inline]
    fn artery(&self, q: V3) -> Option<LabelId> {
        let da = self.aorta.distance(q);
        let dp = self.pa.distance(q);
        let (ea, ep) = (da - self.aorta.r_out, dp - self.pa.r_out);
        if ea.min(ep) >= 0.0 && ea.max(ep) >= self.bridge {
            None
        } else if ea <= ep {
            Some(self.aorta.label_at(da))
        } else {
            Some(self.pa.label_at(dp))
        }
    }

    /// Cavities, valves and myocardium below the top of the basal plate.
    #[inline]
    fn ventricles(&self, q: V3) -> Option<LabelId> {
        let in_myo = self.lv_myo.contains(q);
        if q[2] < self.base {
            if self.lv_cav.contains(q) {
                return Some(LV);
            }
            if !in_myo && self.rv_cav.contains(q) {
                return Some(RV);
            }
        } else if let Some(v) = self.valves.iter().find(|v| v.contains(q)) {
            return Some(v.label);
        }
        (in_myo || self.rv_myo.contains(q)).then_some(MYO)
    }

    /// Valve funnels, atria and interatrial septum.
    #[inline]
    fn atria(&self, q: V3) -> LabelId {
        if q[2] >= self.base {
            if let Some(v) = self.valves[..2]
                .iter()
                .find(|v| q[2] < v.top && v.contains(q))
            {
                return v.label;
            }
        }
        let (in_la, in_ra) = (self.la.contains(q), self.ra.contains(q));
        if !(in_la || in_ra) {
            return BG;
        }
        let (n, m, half) = self.septum;
        let s = dot(n, sub(q, m));
        if s.abs() <= half {
            MYO
        } else if s > 0.0 {
            if in_la { LA } else { BG }
        } else if in_ra {
            RA
        } else {
            BG
        }
    }
}

/// The heart frame's axes in volume coordinates (rows; `dot(row, v)` takes a
/// volume vector into the heart frame): the long axis (apex → base, heart `z`)
/// tilted so that the apex points left (+x), anterior (−y) and inferior (−z).
fn rotation() -> [V3; 3] {
    let (sy, cy) = (-30f64).to_radians().sin_cos();
    let (sx, cx) = (-15f64).to_radians().sin_cos();
    // Volume = Rx · Ry · heart; rows of the inverse (= transpose) map volume → heart.
    let ry = [[cy, 0.0, sy], [0.0, 1.0, 0.0], [-sy, 0.0, cy]];
    let rx = [[1.0, 0.0, 0.0], [0.0, cx, -sx], [0.0, sx, cx]];
    let m: [V3; 3] =
        [0, 1, 2].map(|r| [0, 1, 2].map(|c| (0..3).map(|k| rx[r][k] * ry[k][c]).sum()));
    [0, 1, 2].map(|r| [m[0][r], m[1][r], m[2][r]])
}

/// The parameters `t` where the line `q0 + t·dq` is inside the box.
fn line_in_box(q0: V3, dq: V3, (lo, hi): &(V3, V3)) -> Option<(f64, f64)> {
    let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
    for k in 0..3 {
        let (a, b) = (lo[k] - q0[k], hi[k] - q0[k]);
        if dq[k].abs() < 1e-12 {
            if a > 0.0 || b < 0.0 {
                return None;
            }
        } else {
            t0 = t0.max((a / dq[k]).min(b / dq[k]));
            t1 = t1.min((a / dq[k]).max(b / dq[k]));
        }
    }
    (t0 <= t1).then_some((t0, t1))
}

/// Ascending aorta from the aortic valve, arch toward the back, descending
/// aorta straight down (`down`: the volume's −z in the heart frame) out of the
/// volume.
fn aorta(start: f64, down: V3, r_out: f64, thickness: f64, margin: f64) -> (Tube, V3) {
    let top_up = [0.0, 0.0, 0.42];
    let top_down = [0.3, 0.48, 0.42];
    let bottom = [0, 1, 2].map(|k| top_down[k] + 4.0 * down[k]);
    let pieces = vec![
        Piece::segment([0.0, 0.0, start], top_up, true),
        Piece::arch(top_up, top_down),
        Piece::segment(top_down, bottom, false),
    ];
    (
        Tube::new(pieces, r_out, thickness, [AO, LV], margin),
        top_down,
    )
}

/// Pulmonary trunk from the pulmonary valve, in front of the ascending aorta
/// to its left, then the left branch over the LA and the right branch under
/// the arch, behind the ascending aorta.
fn pulmonary_artery(start: f64, r_out: f64, thickness: f64, margin: f64) -> Tube {
    let root = [-0.2, -0.25, start];
    let rise = [-0.2, -0.25, 0.22];
    let front = [0.18, -0.15, 0.4];
    let fork = [0.17, 0.16, 0.38];
    let pieces = vec![
        Piece::segment(root, rise, true),
        Piece::segment(rise, front, false),
        Piece::segment(front, fork, false),
        Piece::segment(fork, [0.4, 0.3, 0.36], false),
        Piece::segment(fork, [-0.45, 0.215, 0.3], false),
    ];
    Tube::new(pieces, r_out, thickness, [PA, RV], margin)
}

/// Clean labels of every voxel, z slices in parallel.
fn rasterize(heart: &Heart, dims: Dims) -> Vec<LabelId> {
    let n = dims.nx;
    let step = 2.0 / n as f64;
    let coord = |i: usize| (i as f64 + 0.5) * step - 1.0;
    // Voxels whose centre may lie in [lo, hi], one spare voxel on each side.
    let voxels = |(lo, hi): (f64, f64)| {
        let first = ((lo + 1.0) / step - 1.5).max(0.0) as usize;
        let end = ((hi + 1.0) / step + 1.5).clamp(0.0, n as f64) as usize;
        first..end.max(first)
    };
    let mut ids = vec![BG; dims.len()];
    ids.par_chunks_mut(n * n)
        .enumerate()
        .for_each(|(z, slice)| {
            let mut spans = Vec::with_capacity(heart.boxes.len() + 1);
            for (y, row) in slice.chunks_mut(n).enumerate() {
                let (py, pz) = (coord(y), coord(z));
                heart.row_spans(py, pz, &mut spans);
                for &span in &spans {
                    for x in voxels(span) {
                        row[x] = heart.label(heart.to_heart([coord(x), py, pz]));
                    }
                }
            }
        });
    ids
}

/// Gives every voxel without a 6-neighbour of its own label the most common
/// label of its 6-neighbours (myocardium on ties, then the smaller label):
/// rasterizing thin shapes leaves a few such specks.
fn despeckle(ids: &[LabelId], dims: Dims) -> Vec<LabelId> {
    let mut out = ids.to_vec();
    let nx = dims.nx;
    out.par_chunks_mut(nx * dims.ny)
        .enumerate()
        .for_each(|(z, slice)| {
            for (y, row) in slice.chunks_mut(nx).enumerate() {
                let start = dims.index(0, y, z);
                for (x, out) in row.iter_mut().enumerate() {
                    let i = start + x;
                    let own = ids[i];
                    // Most voxels share their label with a neighbour along x.
                    if (x > 0 && ids[i - 1] == own) || (x + 1 < nx && ids[i + 1] == own) {
                        continue;
                    }
                    let mut counts = [0u8; LABELS.len()];
                    for_face_neighbours(dims, i, |k| counts[ids[k] as usize] += 1);
                    if counts[own as usize] == 0 {
                        *out = majority(&counts);
                    }
                }
            }
        });
    out
}

/// The label with the highest count; myocardium first on ties, then the smaller.
fn majority(counts: &[u8; LABELS.len()]) -> LabelId {
    let mut best = MYO;
    for (l, &c) in counts.iter().enumerate() {
        if c > counts[best as usize] {
            best = l as LabelId;
        }
    }
    best
}

/// Calls `f` with the index of every 6-neighbour of voxel `i` inside the volume.
#[inline]
fn for_face_neighbours(dims: Dims, i: usize, mut f: impl FnMut(usize)) {
    let c = dims.coords(i);
    let n = dims.to_array();
    let s = dims.strides();
    for a in 0..3 {
        if c[a] > 0 {
            f(i - s[a]);
        }
        if c[a] + 1 < n[a] {
            f(i + s[a]);
        }
    }
}

// ---------------------------------------------------------------------------
// Noise

/// SplitMix64 finalizer: a well-mixed 64-bit hash.
#[inline]
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Flips voxels next to interfaces (see the module documentation).
fn add_noise(clean: &[LabelId], dims: Dims, p: f64, seed: u64) -> Vec<LabelId> {
    let key = mix(seed);
    // Compare 53 random bits to p: exact for p = 0 and p = 1.
    let threshold = p * (1u64 << 53) as f64;
    let mut out = clean.to_vec();
    let slice_len = dims.nx * dims.ny;
    out.par_chunks_mut(slice_len)
        .enumerate()
        .for_each(|(z, slice)| {
            for (j, out) in slice.iter_mut().enumerate() {
                let i = z * slice_len + j;
                let h = mix(key ^ i as u64);
                if ((h >> 11) as f64) < threshold && on_interface(clean, dims, i) {
                    *out = pick_neighbour(clean, dims, i, mix(h));
                }
            }
        });
    out
}

/// Whether voxel `i` has a 6-neighbour of another label.
#[inline]
fn on_interface(ids: &[LabelId], dims: Dims, i: usize) -> bool {
    let mut other = false;
    for_face_neighbours(dims, i, |k| other |= ids[k] != ids[i]);
    other
}

/// The label of a uniformly chosen 26-neighbour of `i` that differs from it.
#[inline]
fn pick_neighbour(ids: &[LabelId], dims: Dims, i: usize, h: u64) -> LabelId {
    let own = ids[i];
    let mut found = [own; 26];
    let mut count = 0;
    let [x, y, z] = dims.coords(i);
    for dz in -1i64..=1 {
        for dy in -1i64..=1 {
            for dx in -1i64..=1 {
                let (nx, ny, nz) = (x as i64 + dx, y as i64 + dy, z as i64 + dz);
                let inside = |c: i64, n: usize| c >= 0 && (c as usize) < n;
                if !(inside(nx, dims.nx) && inside(ny, dims.ny) && inside(nz, dims.nz)) {
                    continue;
                }
                let l = ids[dims.index(nx as usize, ny as usize, nz as usize)];
                if l != own {
                    found[count] = l;
                    count += 1;
                }
            }
        }
    }
    if count == 0 {
        own
    } else {
        found[(h % count as u64) as usize]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotation_is_orthonormal_and_tilts_the_apex() {
        let r = rotation();
        for a in 0..3 {
            for b in 0..3 {
                let expect = if a == b { 1.0 } else { 0.0 };
                assert!((dot(r[a], r[b]) - expect).abs() < 1e-12);
            }
        }
        // The apex direction (heart −z) in volume coordinates: −(row 2).
        let apex = r[2].map(|c| -c);
        assert!(apex[0] > 0.0 && apex[1] < 0.0 && apex[2] < 0.0, "{apex:?}");
    }

    #[test]
    fn half_circle_distance() {
        let arc = Piece::arch([0.0, 0.0, 0.0], [2.0, 0.0, 0.0]);
        assert!((arc.distance([1.0, 0.0, 1.0])).abs() < 1e-12);
        assert!((arc.distance([1.0, 0.0, 0.5]) - 0.5).abs() < 1e-12);
        assert!((arc.distance([1.0, 0.3, 1.0]) - 0.3).abs() < 1e-12);
        assert_eq!(arc.distance([1.0, 0.0, -0.5]), f64::INFINITY);
    }

    #[test]
    fn noise_hash_is_uniform_enough() {
        let n = 100_000u64;
        let below = (0..n)
            .filter(|&i| ((mix(mix(7) ^ i) >> 11) as f64) < 0.25 * (1u64 << 53) as f64)
            .count();
        assert!((below as f64 / n as f64 - 0.25).abs() < 0.01);
    }
}
