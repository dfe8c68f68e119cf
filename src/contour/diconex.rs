//! DICONEX (B. R. Schlei, "A new computational framework for 2D
//! shape-enclosing contours", 2009): the 2-D analogue of VESTA, as reviewed in
//! section II.A of the VESTA paper.
//!
//! **Iso-contours** ([`iso_contours`]). Pixels with value ≥ iso are *active*.
//! Every pixel edge between an active and an inactive pixel is an *initial
//! contour vector* (ICV) with the active pixel on its left; the DICONEX contour
//! runs through the ICVs' support points — the edge midpoints, or with
//! displacement the point on the range vector (active pixel centre → inactive
//! pixel centre) where linear interpolation meets the iso value — and joins
//! each ICV to the one that starts where it ends. Where two active pixels touch
//! only at a corner (a *point of ambiguity*, two ICVs in and two out), the
//! [`Mode`] decides: disconnect turns back around the same pixel, connect
//! crosses to the other, mixed connects where the mean of the four pixels is at
//! least the iso value. Everything outside the image is inactive, so every
//! contour is closed; shapes run counter-clockwise and holes clockwise.
//!
//! **Label contours** ([`label_contours`]). On a label image every pixel edge
//! between two different labels gets its midpoint; at each pixel corner the
//! midpoints of the edges there are joined as the labels' regions dictate
//! (two edges: one segment; three or four labels meeting: a *junction point*
//! at the corner, joined to each edge midpoint). The result is one polyline
//! per stretch of boundary between two labels — the 2-D analogue of septa's
//! interface patches — and polylines that meet share their junction point.
//!
//! **Coordinates and orientation.** Points are in pixel index coordinates:
//! pixel `(i, j)` (sample `i + width · j`) has its centre at `(i, j)`. For a
//! slice of a volume the two axes are the volume's other two axes in
//! increasing order (see [`crate::io::image2d`]). Counter-clockwise means positive
//! signed area in these coordinates (the active region on the left when the
//! y axis points up; drawn with rows going down, as in image viewers and
//! SVG, it appears clockwise).
//!
//! The link with VESTA (the paper, section II.B): a VESTA surface cut by a
//! principal plane through voxel centres gives the DICONEX contours of that
//! slice, with the same mode and displacement (`tests/contour.rs` checks it).

use glam::DVec2;

use crate::error::{Error, Result};
use crate::iso::{Mode, Scalar, interpolation_fraction};

/// Options of [`iso_contours`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContourOptions {
    /// Pixels with value ≥ `iso` are inside.
    pub iso: f64,
    pub mode: Mode,
    /// Move support points along their range vectors to the interpolated iso
    /// value (off: pixel edge midpoints).
    pub displace: bool,
}

impl ContourOptions {
    /// Mixed mode, displaced points.
    pub fn new(iso: f64) -> Self {
        ContourOptions {
            iso,
            mode: Mode::Mixed,
            displace: true,
        }
    }
}

/// One closed, oriented contour.
#[derive(Clone, Debug, PartialEq)]
pub struct Contour {
    /// Support points in order (the last joins the first).
    pub points: Vec<DVec2>,
}

impl Contour {
    /// Signed area (shoelace): positive for shapes, negative for holes.
    pub fn signed_area(&self) -> f64 {
        let n = self.points.len();
        (0..n)
            .map(|k| self.points[k].perp_dot(self.points[(k + 1) % n]))
            .sum::<f64>()
            * 0.5
    }

    /// Whether it runs clockwise (encloses a hole of a shape).
    pub fn is_hole(&self) -> bool {
        self.signed_area() < 0.0
    }

    /// Its segments, each from a point to the next.
    pub fn segments(&self) -> impl Iterator<Item = (DVec2, DVec2)> + '_ {
        let n = self.points.len();
        (0..n).map(move |k| (self.points[k], self.points[(k + 1) % n]))
    }
}

/// The DICONEX contours of an image.
#[derive(Clone, Debug, Default)]
pub struct Contours {
    pub width: usize,
    pub height: usize,
    /// In a fixed order (by the first boundary pixel edge of each).
    pub contours: Vec<Contour>,
    /// Pixels with value ≥ iso.
    pub active_pixels: u64,
    /// Corners where two active pixels touch only diagonally, and how many of
    /// them were joined.
    pub points_of_ambiguity: u64,
    pub joined: u64,
}

impl Contours {
    /// Total number of support points (= boundary pixel edges).
    pub fn point_count(&self) -> usize {
        self.contours.iter().map(|c| c.points.len()).sum()
    }

    /// Number of clockwise contours.
    pub fn hole_count(&self) -> usize {
        self.contours.iter().filter(|c| c.is_hole()).count()
    }
}

/// The padded pixel grid: one inactive (outside) pixel around the image.
/// Padded pixel `p = px + pw · py` is image pixel `(px − 1, py − 1)`.
#[derive(Clone, Copy)]
struct Pad {
    w: usize,
    h: usize,
    pw: usize,
    ph: usize,
}

impl Pad {
    fn new(w: usize, h: usize) -> Self {
        Pad {
            w,
            h,
            pw: w + 2,
            ph: h + 2,
        }
    }

    fn len(&self) -> usize {
        self.pw * self.ph
    }

    /// Image sample index of padded pixel `p`, if inside the image.
    #[inline]
    fn pixel(&self, p: usize) -> Option<usize> {
        let (px, py) = (p % self.pw, p / self.pw);
        ((1..=self.w).contains(&px) && (1..=self.h).contains(&py))
            .then(|| (px - 1) + self.w * (py - 1))
    }

    /// Centre of padded pixel `p` in image coordinates.
    #[inline]
    fn centre(&self, p: usize) -> DVec2 {
        DVec2::new((p % self.pw) as f64 - 1.0, (p / self.pw) as f64 - 1.0)
    }

    /// Position of corner `c` (the low-x, low-y corner of padded pixel `c`).
    #[inline]
    fn corner(&self, c: usize) -> DVec2 {
        self.centre(c) - DVec2::splat(0.5)
    }
}

/// A pixel edge: `2 p` is the edge on the low-x side of padded pixel `p`
/// (between `p − 1` and `p`), `2 p + 1` the one on its low-y side (between
/// `p − pw` and `p`).
type Edge = usize;

/// Whether both pixels of edge `e` exist on the padded grid.
#[inline]
fn edge_exists(pad: &Pad, e: Edge) -> bool {
    let p = e / 2;
    p < pad.len()
        && if e & 1 == 0 {
            p % pad.pw >= 1
        } else {
            p >= pad.pw
        }
}

#[inline]
fn edge_pixels(pad: &Pad, e: Edge) -> (usize, usize) {
    let p = e / 2;
    if e & 1 == 0 {
        (p - 1, p)
    } else {
        (p - pad.pw, p)
    }
}

/// The four edges at corner `c` (S, N, W, E) and the four pixels around it
/// (q0 = −x −y, q1 = +x −y, q2 = −x +y, q3 = +x +y). S separates q0|q1, N
/// q2|q3, W q0|q2, E q1|q3.
#[inline]
fn corner_edges(pad: &Pad, c: usize) -> [Edge; 4] {
    [2 * (c - pad.pw), 2 * c, 2 * (c - 1) + 1, 2 * c + 1]
}

#[inline]
fn corner_pixels(pad: &Pad, c: usize) -> [usize; 4] {
    [c - 1 - pad.pw, c - pad.pw, c - 1, c]
}

const S: usize = 0;
const N: usize = 1;
const W: usize = 2;
const E: usize = 3;

/// The two corners of an edge: (the one at its low end, the one at its high
/// end) along the edge's direction.
#[inline]
fn edge_corners(pad: &Pad, e: Edge) -> (usize, usize) {
    let p = e / 2;
    if e & 1 == 0 {
        (p, p + pad.pw)
    } else {
        (p, p + 1)
    }
}

/// DICONEX iso-contours of a `width × height` image (samples x fastest).
pub fn iso_contours<T: Scalar>(
    values: &[T],
    width: usize,
    height: usize,
    opts: &ContourOptions,
) -> Result<Contours> {
    if opts.iso.is_nan() {
        return Err(Error::invalid("the iso value is NaN"));
    }
    check_size(values.len(), width, height)?;
    let pad = Pad::new(width, height);
    let mut active = vec![false; pad.len()];
    let mut n_active = 0;
    for (p, a) in active.iter_mut().enumerate() {
        if let Some(i) = pad.pixel(p) {
            *a = values[i].to_f64() >= opts.iso;
            n_active += *a as u64;
        }
    }
    let value = |p: usize| pad.pixel(p).map(|i| values[i].to_f64());
    let is_boundary = |e: Edge| {
        let (a, b) = edge_pixels(&pad, e);
        active[a] != active[b]
    };
    let support = |e: Edge| -> DVec2 {
        let (a, b) = edge_pixels(&pad, e);
        let (ca, cb) = (pad.centre(a), pad.centre(b));
        let mid = (ca + cb) * 0.5;
        if !opts.displace {
            return mid;
        }
        let (Some(va), Some(vb)) = (value(a), value(b)) else {
            return mid;
        };
        // from the active centre toward the inactive one
        let (pa, pi, va, vi) = if active[a] {
            (ca, cb, va, vb)
        } else {
            (cb, ca, vb, va)
        };
        pa + (pi - pa) * interpolation_fraction(va, vi, opts.iso)
    };
    // where an ICV ends: x edges run down (toward −y) with the active pixel
    // at +x, y edges run toward +x with the active pixel at +y
    let end_corner = |e: Edge| -> usize {
        let (lo, hi) = edge_corners(&pad, e);
        let (_, b) = edge_pixels(&pad, e);
        match (e & 1, active[b]) {
            (0, true) => lo,
            (0, false) => hi,
            (_, true) => hi,
            (_, false) => lo,
        }
    };
    let mut out = Contours {
        width,
        height,
        ..Default::default()
    };
    let mut visited = vec![false; 2 * pad.len()];
    let mut poa = 0u64;
    let mut joined = 0u64;
    // the successor of the ICV that ends at corner `c` through edge slot
    // `slot`, whether the corner is a point of ambiguity, and if it is joined
    let next = |c: usize, slot: usize| -> (Edge, bool, bool) {
        let q = corner_pixels(&pad, c).map(|p| active[p]);
        let edges = corner_edges(&pad, c);
        // outgoing: S if q1, N if q2, W if q0, E if q3
        let diagonal = q[0] == q[3] && q[1] == q[2] && q[0] != q[1];
        if !diagonal {
            let out = [
                (S, q[1] && !q[0]),
                (N, q[2] && !q[3]),
                (W, q[0] && !q[2]),
                (E, q[3] && !q[1]),
            ]
            .into_iter()
            .find(|&(_, o)| o)
            .map(|(s, _)| s)
            .expect("a boundary corner has one outgoing ICV");
            return (edges[out], false, false);
        }
        let connect = match opts.mode {
            Mode::Disconnect => false,
            Mode::Connect => true,
            Mode::Mixed => {
                let sum: f64 = corner_pixels(&pad, c)
                    .iter()
                    .map(|&p| value(p).unwrap_or(f64::NEG_INFINITY))
                    .sum();
                sum / 4.0 >= opts.iso
            }
        };
        // q0 & q3 active: in S (q0), N (q3); out W (q0), E (q3).
        // q1 & q2 active: in E (q1), W (q2); out S (q1), N (q2).
        let out = match (q[0], slot, connect) {
            (true, S, false) => W,
            (true, N, false) => E,
            (true, S, true) => E,
            (true, N, true) => W,
            (false, E, false) => S,
            (false, W, false) => N,
            (false, E, true) => N,
            (false, W, true) => S,
            _ => unreachable!("not an incoming ICV"),
        };
        (edges[out], true, connect)
    };
    for start in 0..2 * pad.len() {
        if !edge_exists(&pad, start) || visited[start] || !is_boundary(start) {
            continue;
        }
        let mut points = Vec::new();
        let mut e = start;
        loop {
            visited[e] = true;
            points.push(support(e));
            let c = end_corner(e);
            let slot = corner_edges(&pad, c)
                .iter()
                .position(|&x| x == e)
                .expect("an edge is at its end corner");
            let (n, ambiguous, connect) = next(c, slot);
            // count each point of ambiguity once (at its S or E incoming ICV)
            if ambiguous && (slot == S || slot == E) {
                poa += 1;
                joined += connect as u64;
            }
            e = n;
            if e == start {
                break;
            }
        }
        out.contours.push(Contour { points });
    }
    out.active_pixels = n_active;
    out.points_of_ambiguity = poa;
    out.joined = joined;
    Ok(out)
}

fn check_size(len: usize, width: usize, height: usize) -> Result<()> {
    if width == 0 || height == 0 {
        return Err(Error::invalid(format!(
            "an image of {width} × {height} pixels has no pixels"
        )));
    }
    if width.checked_mul(height) != Some(len) {
        return Err(Error::invalid(format!(
            "{len} samples for {width} × {height} pixels"
        )));
    }
    if (width + 2)
        .checked_mul(height + 2)
        .and_then(|n| n.checked_mul(2))
        .is_none_or(|n| n > u32::MAX as usize)
    {
        return Err(Error::invalid(format!(
            "{width} × {height} pixels: more than septa's 2-D limit"
        )));
    }
    Ok(())
}

// ------------------------------------------------------------------ labels

/// Options of [`label_contours`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LabelContourOptions {
    /// Label of everything outside the image (`None`: the most frequent
    /// label on the image border).
    pub outside: Option<i64>,
}

/// A polyline between two labels.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Polyline {
    /// `[a, b]` with `a < b`: label `a` lies on the left (the polyline runs
    /// counter-clockwise around `a`'s region).
    pub labels: [i64; 2],
    /// Indices into [`LabelContours::points`]; open polylines start and end at
    /// junction points.
    pub points: Vec<u32>,
    /// Closed (the last point joins the first; no junction on it).
    pub closed: bool,
}

/// The label contours of a label image.
#[derive(Clone, Debug, Default)]
pub struct LabelContours {
    pub width: usize,
    pub height: usize,
    /// The outside label used.
    pub outside: i64,
    /// Edge midpoints, then junction points (pixel corners where three or four
    /// labels meet).
    pub points: Vec<DVec2>,
    /// Points from this index on are junction points.
    pub first_junction: usize,
    pub polylines: Vec<Polyline>,
    /// Corners where one label's pixels touch only diagonally with the other
    /// two pixels of one other label (resolved toward the smaller label value).
    pub checkerboards: u64,
}

impl LabelContours {
    /// Number of junction points.
    pub fn junction_count(&self) -> usize {
        self.points.len() - self.first_junction
    }

    /// Whether point `i` is a junction point.
    pub fn is_junction(&self, i: u32) -> bool {
        i as usize >= self.first_junction
    }
}

/// How the boundary edges meet at one corner.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Meet {
    /// No boundary edge.
    None,
    /// Pairs of edge slots joined by a segment (one or two pairs).
    Pairs([(usize, usize); 2], usize),
    /// Three or four labels: every boundary edge joins a junction at the corner.
    Junction,
}

fn meet(l: [i64; 4]) -> (Meet, bool) {
    let b = [l[0] != l[1], l[2] != l[3], l[0] != l[2], l[1] != l[3]]; // S N W E
    let k = b.iter().filter(|&&x| x).count();
    match k {
        0 => (Meet::None, false),
        2 => {
            let s: Vec<usize> = (0..4).filter(|&i| b[i]).collect();
            (Meet::Pairs([(s[0], s[1]), (0, 0)], 1), false)
        }
        3 => (Meet::Junction, false),
        _ => {
            let d03 = l[0] == l[3];
            let d12 = l[1] == l[2];
            // which diagonal pair is joined across the corner
            let (join03, checker) = match (d03, d12) {
                (true, true) => (l[0] < l[1], true),
                (true, false) => (true, false),
                (false, true) => (false, false),
                (false, false) => return (Meet::Junction, false),
            };
            let pairs = if join03 {
                // arcs around q1 (S, E) and q2 (W, N)
                [(S, E), (W, N)]
            } else {
                // arcs around q0 (S, W) and q3 (N, E)
                [(S, W), (N, E)]
            };
            (Meet::Pairs(pairs, 2), checker)
        }
    }
}

/// Label contours of a `width × height` label image (samples x fastest).
pub fn label_contours(
    labels: &[i64],
    width: usize,
    height: usize,
    opts: &LabelContourOptions,
) -> Result<LabelContours> {
    check_size(labels.len(), width, height)?;
    let pad = Pad::new(width, height);
    let outside = opts
        .outside
        .unwrap_or_else(|| border_label(labels, width, height));
    let mut lab = vec![outside; pad.len()];
    for (p, l) in lab.iter_mut().enumerate() {
        if let Some(i) = pad.pixel(p) {
            *l = labels[i];
        }
    }
    let is_boundary = |e: Edge| {
        let (a, b) = edge_pixels(&pad, e);
        lab[a] != lab[b]
    };
    let corner_meet = |c: usize| meet(corner_pixels(&pad, c).map(|p| lab[p]));
    // dense point ids: boundary edges in edge order
    let mut point_of = vec![u32::MAX; 2 * pad.len()];
    let mut points = Vec::new();
    for (e, id) in point_of.iter_mut().enumerate() {
        if edge_exists(&pad, e) && is_boundary(e) {
            *id = points.len() as u32;
            let (a, b) = edge_pixels(&pad, e);
            points.push((pad.centre(a) + pad.centre(b)) * 0.5);
        }
    }
    let first_junction = points.len();
    // the partner of edge e at corner c: another edge, or the junction there
    enum Partner {
        Edge(Edge),
        Junction,
    }
    let partner = |c: usize, e: Edge| -> Partner {
        let edges = corner_edges(&pad, c);
        let slot = edges.iter().position(|&x| x == e).expect("edge at corner");
        match corner_meet(c).0 {
            Meet::Pairs(pairs, n) => {
                for &(a, b) in &pairs[..n] {
                    if a == slot {
                        return Partner::Edge(edges[b]);
                    }
                    if b == slot {
                        return Partner::Edge(edges[a]);
                    }
                }
                unreachable!("a boundary edge is paired at its corner")
            }
            Meet::Junction => Partner::Junction,
            Meet::None => unreachable!("a boundary edge's corner has boundary edges"),
        }
    };
    let mut junction_of = std::collections::HashMap::new();
    let mut checkerboards = 0;
    let mut junction_corners = Vec::new();
    for c in 0..pad.len() {
        let (px, py) = (c % pad.pw, c / pad.pw);
        if px == 0 || py == 0 {
            continue;
        }
        let (m, checker) = corner_meet(c);
        checkerboards += checker as u64;
        if m == Meet::Junction {
            junction_of.insert(c, points.len() as u32);
            points.push(pad.corner(c));
            junction_corners.push(c);
        }
    }
    let mut visited = vec![false; 2 * pad.len()];
    let mut polylines = Vec::new();
    // walks from edge `e` entered at corner `from` until a junction or back to `e`
    let walk = |e0: Edge, from: usize, visited: &mut Vec<bool>| -> (Vec<Edge>, Option<usize>) {
        let mut edges = Vec::new();
        let (mut e, mut c_in) = (e0, from);
        loop {
            visited[e] = true;
            edges.push(e);
            let (lo, hi) = edge_corners(&pad, e);
            let c_out = if c_in == lo { hi } else { lo };
            match partner(c_out, e) {
                Partner::Junction => return (edges, Some(c_out)),
                Partner::Edge(n) => {
                    if n == e0 {
                        return (edges, None);
                    }
                    e = n;
                    c_in = c_out;
                }
            }
        }
    };
    // orientation: label a (the smaller) on the left of the first edge's traversal
    let finish = |edges: &[Edge], first_from: usize, mut ids: Vec<u32>, closed: bool| -> Polyline {
        let e = edges[0];
        let (a, b) = edge_pixels(&pad, e);
        let (lo, _) = edge_corners(&pad, e);
        let forward = first_from == lo; // traversed toward +y (x edge) or +x (y edge)
        // left of a +y traversal of an x edge is pixel a (−x); of a +x
        // traversal of a y edge, pixel b (+y)
        let left = match (e & 1, forward) {
            (0, true) | (1, false) => lab[a],
            _ => lab[b],
        };
        let right = if left == lab[a] { lab[b] } else { lab[a] };
        if left > right {
            ids.reverse();
        }
        Polyline {
            labels: [left.min(right), left.max(right)],
            points: ids,
            closed,
        }
    };
    for &c in &junction_corners {
        let j = junction_of[&c];
        for e in corner_edges(&pad, c) {
            if point_of[e] == u32::MAX || visited[e] {
                continue;
            }
            let (edges, end) = walk(e, c, &mut visited);
            let end = end.expect("a walk from a junction ends at a junction");
            let mut ids = vec![j];
            ids.extend(edges.iter().map(|&x| point_of[x]));
            ids.push(junction_of[&end]);
            polylines.push(finish(&edges, c, ids, false));
        }
    }
    for e in 0..2 * pad.len() {
        if point_of[e] == u32::MAX || visited[e] {
            continue;
        }
        let (lo, _) = edge_corners(&pad, e);
        let (edges, end) = walk(e, lo, &mut visited);
        debug_assert!(end.is_none(), "loops without junctions were left");
        let ids = edges.iter().map(|&x| point_of[x]).collect();
        polylines.push(finish(&edges, lo, ids, true));
    }
    Ok(LabelContours {
        width,
        height,
        outside,
        points,
        first_junction,
        polylines,
        checkerboards,
    })
}

/// The most frequent label on the image border (ties: the smallest).
fn border_label(labels: &[i64], w: usize, h: usize) -> i64 {
    let mut counts = std::collections::BTreeMap::new();
    for j in 0..h {
        for i in 0..w {
            if i == 0 || j == 0 || i == w - 1 || j == h - 1 {
                *counts.entry(labels[i + w * j]).or_insert(0u64) += 1;
            }
        }
    }
    let mut best = (0u64, 0i64);
    for (&l, &n) in &counts {
        if n > best.0 {
            best = (n, l);
        }
    }
    best.1
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(v: &[u8], w: usize, h: usize, mode: Mode, displace: bool) -> Contours {
        let o = ContourOptions {
            iso: 1.0,
            mode,
            displace,
        };
        iso_contours(v, w, h, &o).unwrap()
    }

    #[test]
    fn one_pixel_is_a_counter_clockwise_diamond() {
        let c = run(&[0, 0, 0, 0, 1, 0, 0, 0, 0], 3, 3, Mode::Mixed, false);
        assert_eq!(c.contours.len(), 1);
        let k = &c.contours[0];
        assert_eq!(k.points.len(), 4);
        assert_eq!(k.signed_area(), 0.5);
        for p in &k.points {
            assert_eq!((p.x - 1.0).abs() + (p.y - 1.0).abs(), 0.5);
        }
        // at the image border the midpoints stay (the outside has no value)
        let c = run(&[1], 1, 1, Mode::Mixed, true);
        assert_eq!(c.contours[0].signed_area(), 0.5);
    }

    #[test]
    fn a_ring_has_a_shape_and_a_hole() {
        let mut v = vec![1u8; 9];
        v[4] = 0;
        let c = run(&v, 3, 3, Mode::Mixed, false);
        assert_eq!(c.contours.len(), 2);
        assert_eq!(c.hole_count(), 1);
        let areas: Vec<f64> = c.contours.iter().map(|k| k.signed_area()).collect();
        assert!(areas.contains(&-0.5), "{areas:?}");
        assert_eq!(c.point_count(), 12 + 4);
    }

    #[test]
    fn points_of_ambiguity_follow_the_mode() {
        // two pixels touching at a corner
        let v = [1u8, 0, 0, 1];
        assert_eq!(run(&v, 2, 2, Mode::Disconnect, false).contours.len(), 2);
        let c = run(&v, 2, 2, Mode::Connect, false);
        assert_eq!(
            (c.contours.len(), c.points_of_ambiguity, c.joined),
            (1, 1, 1)
        );
        assert_eq!(c.contours[0].points.len(), 8);
        // mixed: mean of (1, 0, 0, 1) vs iso 1 → apart; with bright pixels joined
        assert_eq!(run(&v, 2, 2, Mode::Mixed, false).contours.len(), 2);
        assert_eq!(
            run(&[3, 0, 0, 3], 2, 2, Mode::Mixed, false).contours.len(),
            1
        );
        // the other diagonal too
        assert_eq!(
            run(&[0, 1, 1, 0], 2, 2, Mode::Disconnect, false)
                .contours
                .len(),
            2
        );
        assert_eq!(
            run(&[0, 1, 1, 0], 2, 2, Mode::Connect, false)
                .contours
                .len(),
            1
        );
        // a hole touching another hole at a corner: inactive pixels diagonal
        let v = [1u8, 1, 1, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1, 1, 1, 1];
        let d = run(&v, 4, 4, Mode::Disconnect, false);
        let c = run(&v, 4, 4, Mode::Connect, false);
        // disconnect keeps the active pixels apart: the two holes merge
        assert_eq!((d.contours.len(), d.hole_count()), (2, 1));
        assert_eq!((c.contours.len(), c.hole_count()), (3, 2));
    }

    #[test]
    fn displacement_interpolates_along_the_range_vector() {
        let v = [0.0, 0.0, 0.0, 0.0, 133.0, 0.0, 0.0, 0.0, 0.0];
        let o = ContourOptions {
            iso: 100.0,
            mode: Mode::Mixed,
            displace: true,
        };
        let c = iso_contours(&v, 3, 3, &o).unwrap();
        let t = 33.0 / 133.0;
        for p in &c.contours[0].points {
            assert!(((p.x - 1.0).abs() + (p.y - 1.0).abs() - t).abs() < 1e-12);
        }
    }

    #[test]
    fn bad_input_is_an_error() {
        let o = ContourOptions::new(1.0);
        assert!(iso_contours(&[0u8; 5], 2, 2, &o).is_err());
        assert!(iso_contours(&[0u8; 0], 0, 2, &o).is_err());
        assert!(iso_contours(&[0u8; 4], 2, 2, &ContourOptions::new(f64::NAN)).is_err());
        let lo = LabelContourOptions { outside: None };
        assert!(label_contours(&[0; 3], 2, 2, &lo).is_err());
    }

    fn labels(l: &[i64], w: usize, h: usize) -> LabelContours {
        label_contours(l, w, h, &LabelContourOptions { outside: Some(0) }).unwrap()
    }

    #[test]
    fn two_labels_give_one_closed_counter_clockwise_polyline() {
        let lc = labels(&[0, 0, 0, 0, 7, 0, 0, 0, 0], 3, 3);
        assert_eq!(lc.polylines.len(), 1);
        assert_eq!(lc.junction_count(), 0);
        let pl = &lc.polylines[0];
        assert_eq!(pl.labels, [0, 7]);
        assert!(pl.closed);
        let pts: Vec<DVec2> = pl.points.iter().map(|&i| lc.points[i as usize]).collect();
        // label 0 (the outside) on the left: clockwise around the pixel
        let area: f64 = (0..4)
            .map(|k| pts[k].perp_dot(pts[(k + 1) % 4]))
            .sum::<f64>()
            / 2.0;
        assert_eq!(area, -0.5);
        // and with the pixel's label the smaller one, counter-clockwise
        let lc = label_contours(
            &[9, 9, 9, 9, 2, 9, 9, 9, 9],
            3,
            3,
            &LabelContourOptions { outside: None },
        )
        .unwrap();
        assert_eq!(lc.outside, 9);
        let pl = &lc.polylines[0];
        assert_eq!(pl.labels, [2, 9]);
        let pts: Vec<DVec2> = pl.points.iter().map(|&i| lc.points[i as usize]).collect();
        let area: f64 = (0..4)
            .map(|k| pts[k].perp_dot(pts[(k + 1) % 4]))
            .sum::<f64>()
            / 2.0;
        assert_eq!(area, 0.5);
    }

    #[test]
    fn three_labels_meet_at_shared_junctions() {
        // left half 1, right half 2, in a frame of 0
        let (w, h) = (4, 3);
        let l: Vec<i64> = (0..w * h).map(|k| if k % w < 2 { 1 } else { 2 }).collect();
        let lc = labels(&l, w, h);
        // two junctions (top and bottom of the 1|2 border); pairs {0,1}, {0,2}, {1,2}
        assert_eq!(lc.junction_count(), 2);
        let mut pairs: Vec<[i64; 2]> = lc.polylines.iter().map(|p| p.labels).collect();
        pairs.sort();
        assert_eq!(pairs, [[0, 1], [0, 2], [1, 2]]);
        for pl in &lc.polylines {
            assert!(!pl.closed);
            assert!(lc.is_junction(pl.points[0]) && lc.is_junction(*pl.points.last().unwrap()));
            assert!(
                pl.points[1..pl.points.len() - 1]
                    .iter()
                    .all(|&i| !lc.is_junction(i))
            );
        }
        // every junction is the end of exactly three polylines
        for j in lc.first_junction..lc.points.len() {
            let ends = lc
                .polylines
                .iter()
                .flat_map(|p| [p.points[0], *p.points.last().unwrap()])
                .filter(|&i| i as usize == j)
                .count();
            assert_eq!(ends, 3);
        }
        // each edge midpoint is on exactly one polyline
        let mut seen = vec![0; lc.points.len()];
        for pl in &lc.polylines {
            for &i in &pl.points {
                seen[i as usize] += 1;
            }
        }
        assert!(seen[..lc.first_junction].iter().all(|&n| n == 1));
        // the 1|2 polyline runs with label 1 on its left: upward (toward +y)
        let p12 = lc.polylines.iter().find(|p| p.labels == [1, 2]).unwrap();
        let (a, b) = (
            lc.points[p12.points[0] as usize],
            lc.points[*p12.points.last().unwrap() as usize],
        );
        assert!(b.y > a.y && a.x == 1.5 && b.x == 1.5, "{a} {b}");
    }

    #[test]
    fn checkerboards_join_the_smaller_label() {
        let lc = label_contours(
            &[3, 5, 5, 3],
            2,
            2,
            &LabelContourOptions { outside: Some(3) },
        )
        .unwrap();
        assert_eq!(lc.checkerboards, 1);
        // 3 joined across the centre: the two 5-pixels are separate loops
        assert_eq!(lc.polylines.len(), 2);
        assert!(
            lc.polylines
                .iter()
                .all(|p| p.closed && p.labels == [3, 5] && p.points.len() == 4)
        );
        let lc = label_contours(
            &[3, 5, 5, 3],
            2,
            2,
            &LabelContourOptions { outside: Some(5) },
        )
        .unwrap();
        // in a frame of 5, the two 3-pixels are one shape (one loop of 8 points)
        assert_eq!(lc.polylines.len(), 1);
        assert_eq!(lc.polylines[0].points.len(), 8);
        // four different labels: one junction with four polylines
        let lc = labels(&[1, 2, 3, 4], 2, 2);
        assert!(lc.junction_count() >= 1);
        let centre = lc
            .points
            .iter()
            .position(|p| *p == DVec2::splat(0.5))
            .unwrap() as u32;
        let ends = lc
            .polylines
            .iter()
            .filter(|p| p.points[0] == centre || *p.points.last().unwrap() == centre)
            .count();
        assert_eq!(ends, 4);
    }
}
