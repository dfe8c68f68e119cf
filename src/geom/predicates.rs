//! Geometric predicates and constructions on triangles and segments: the
//! triangle–triangle intersection test that understands shared vertices and
//! edges, nearest points on triangles and segments, degeneracy and shape
//! quality, and outward rounding to `f32`.

use glam::DVec3;

/// Twice-area threshold (relative to the squared longest edge) below which a
/// triangle counts as degenerate.
pub const DEGENERATE: f64 = 1e-9;

/// Whether triangle (a, b, c) has (almost) zero area.
#[inline]
pub fn is_degenerate(a: DVec3, b: DVec3, c: DVec3) -> bool {
    let cross = (b - a).cross(c - a).length();
    let longest = (b - a)
        .length_squared()
        .max((c - a).length_squared())
        .max((c - b).length_squared());
    cross <= DEGENERATE * longest
}

/// Triangle quality in (0, 1]: 4√3 · area / Σ edge², 1 for an equilateral triangle.
#[inline]
pub fn triangle_quality(a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let area2 = (b - a).cross(c - a).length();
    let sum = (b - a).length_squared() + (c - b).length_squared() + (a - c).length_squared();
    if sum == 0.0 {
        0.0
    } else {
        2.0 * 3f64.sqrt() * area2 / sum
    }
}

/// The point of triangle `abc` nearest to `p` (Ericson, *Real-Time Collision
/// Detection* §5.1.5). Degenerate triangles (zero area, coincident corners)
/// are handled as their longest segment.
///
/// ```
/// use glam::DVec3;
/// use septa::geom::predicates::closest_point_on_triangle;
/// let (a, b, c) = (DVec3::ZERO, DVec3::X, DVec3::Y);
/// assert_eq!(closest_point_on_triangle(DVec3::new(0.25, 0.25, 3.0), a, b, c), DVec3::new(0.25, 0.25, 0.0));
/// assert_eq!(closest_point_on_triangle(DVec3::new(-1.0, -1.0, 0.0), a, b, c), a);
/// ```
pub fn closest_point_on_triangle(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> DVec3 {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let den = d1 - d3;
        return if den > 0.0 { a + ab * (d1 / den) } else { a };
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let den = d2 - d6;
        return if den > 0.0 { a + ac * (d2 / den) } else { a };
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        let den = (d4 - d3) + (d5 - d6);
        return if den > 0.0 {
            b + (c - b) * ((d4 - d3) / den)
        } else {
            b
        };
    }
    let den = va + vb + vc;
    if den > 0.0 && den.is_finite() {
        let v = vb / den;
        let w = vc / den;
        let q = a + ab * v + ac * w;
        if q.is_finite() {
            return q;
        }
    }
    // Degenerate: the nearest of the three edges.
    let s = [
        closest_on_segment(p, a, b),
        closest_on_segment(p, b, c),
        closest_on_segment(p, c, a),
    ];
    let mut best = s[0];
    for q in &s[1..] {
        if p.distance_squared(*q) < p.distance_squared(best) {
            best = *q;
        }
    }
    best
}

/// The point of segment `[a, b]` nearest to `p` (`a` when the segment is a
/// point or not finite).
pub fn closest_on_segment(p: DVec3, a: DVec3, b: DVec3) -> DVec3 {
    let d = b - a;
    let l2 = d.length_squared();
    if l2.is_nan() || l2 <= 0.0 || !l2.is_finite() {
        return a;
    }
    a + d * ((p - a).dot(d) / l2).clamp(0.0, 1.0)
}

/// The largest `f32` not above `x` (NaN: the lowest `f32`).
pub(crate) fn f32_down(x: f64) -> f32 {
    let f = x as f32;
    if f.is_nan() {
        return f32::MIN;
    }
    if (f as f64) <= x {
        f
    } else if f == f32::INFINITY {
        f32::MAX
    } else {
        f - (f.abs() * f32::EPSILON).max(f32::MIN_POSITIVE)
    }
}

/// The smallest `f32` not below `x` (NaN: the largest `f32`).
pub(crate) fn f32_up(x: f64) -> f32 {
    -f32_down(-x)
}

/// Whether triangles `s` and `t` intersect beyond their shared vertices/edge.
pub fn triangles_intersect(p: &[DVec3], s: [u32; 3], t: [u32; 3]) -> bool {
    // (built element by element: `map` copies through the stack in a way
    // that stalls store forwarding)
    let sp = [p[s[0] as usize], p[s[1] as usize], p[s[2] as usize]];
    let tp = [p[t[0] as usize], p[t[1] as usize], p[t[2] as usize]];
    let sk = [s[0] as u64, s[1] as u64, s[2] as u64];
    let tk = [t[0] as u64, t[1] as u64, t[2] as u64];
    triangles_cross(&sp, &sk, &tp, &tk)
}

/// [`triangles_intersect`] for triangles given by their corner positions and
/// vertex identities (`sk`, `tk`: equal keys are the same vertex, which the
/// triangles may share without intersecting).
/// The two corners after corner `i` of a triangle, in order (a table: `% 3`
/// on a run-time index costs a multiply-and-shift per corner in the guard's
/// hottest test).
const AFTER: [[usize; 2]; 3] = [[1, 2], [2, 0], [0, 1]];

pub fn triangles_cross(sp: &[DVec3; 3], sk: &[u64; 3], tp: &[DVec3; 3], tk: &[u64; 3]) -> bool {
    let mut shared = [(0usize, 0usize); 3];
    let mut n_shared = 0;
    for (i, sv) in sk.iter().enumerate() {
        for (j, tv) in tk.iter().enumerate() {
            if sv == tv {
                shared[n_shared] = (i, j);
                n_shared += 1;
            }
        }
    }
    let shared = &shared[..n_shared];
    if let [(i, j)] = *shared {
        // neighbours around a common vertex, the usual pair in a mesh: apart
        // when their sectors at it are apart, seen along their normals
        let ([i1, i2], [j1, j2]) = (AFTER[i], AFTER[j]);
        let (s1, s2) = (sp[i1], sp[i2]);
        let (t1, t2) = (tp[j1], tp[j2]);
        if beside_plane(sp[i], s1, s2, t1, t2)
            || beside_plane(sp[i], t1, t2, s1, s2)
            || sectors_apart(sp[i], s1, s2, t1, t2)
        {
            return false;
        }
    }
    if n_shared < 2 && (separated_by_plane(sp, tp) || separated_by_plane(tp, sp)) {
        return false;
    }
    match shared.len() {
        0 => disjoint_intersect(sp, tp),
        1 => {
            let (i, j) = shared[0];
            // the opposite edge of each against the other triangle
            let ([i1, i2], [j1, j2]) = (AFTER[i], AFTER[j]);
            let (s1, s2) = (sp[i1], sp[i2]);
            let (t1, t2) = (tp[j1], tp[j2]);
            segment_hits_triangle(s1, s2, tp)
                || segment_hits_triangle(t1, t2, sp)
                || coplanar_wedges_overlap(sp[i], s1, s2, t1, t2)
        }
        2 => {
            // folded onto each other: coplanar with both free vertices on one side
            let free_s = (0..3)
                .find(|&i| !shared.iter().any(|x| x.0 == i))
                .expect("one free vertex");
            let free_t = (0..3)
                .find(|&j| !shared.iter().any(|x| x.1 == j))
                .expect("one free vertex");
            let (a, b) = (sp[shared[0].0], sp[shared[1].0]);
            let n = (b - a).cross(sp[free_s] - a);
            if off_plane(n, b - a, tp[free_t] - a) {
                return false;
            }
            // same side of the shared edge within the plane
            let e = b - a;
            let side = |q: DVec3| e.cross(q - a).dot(n);
            side(sp[free_s]) * side(tp[free_t]) > 0.0
        }
        _ => true,
    }
}

/// Whether triangles (v, s1, s2) and (v, t1, t2), which share the vertex v,
/// are shown to meet only there because t1 and t2 lie strictly on one side
/// of the plane of the first (then the second meets that plane only at v).
/// The cheap test for neighbours on a curved surface; `false` says only
/// "not shown this way". "Strictly" has a margin of 1e-9 |s1 − v| |s2 − v|
/// |t − v|: the computed normal is off the exact one by rounding of
/// order 1e-16 |s1 − v| |s2 − v| (however thin the triangle), so a side
/// beyond the margin is the exact side; and the margin is wider than the
/// tolerances of the tests behind it, so that this shortcut never calls
/// apart what they would call touching.
#[inline]
fn beside_plane(v: DVec3, s1: DVec3, s2: DVec3, t1: DVec3, t2: DVec3) -> bool {
    let (a, b) = (s1 - v, s2 - v);
    let n = a.cross(b);
    let (r1, r2) = (t1 - v, t2 - v);
    let (d1, d2) = (n.dot(r1), n.dot(r2));
    if !(d1 * d2 > 0.0) {
        return false;
    }
    // d² > (1e-9 |a| |b| |r|)² for both, compared squared (no roots; an
    // underflow only makes the test fail)
    let m = 1e-18 * a.length_squared() * b.length_squared();
    d1 * d1 > m * r1.length_squared() && d2 * d2 > m * r2.length_squared()
}

/// Whether triangles (v, s1, s2) and (v, t1, t2), which share the vertex v,
/// are shown to meet only there: seen along the sum of their unit normals,
/// both keep their orientation and their sectors at v are apart (the
/// second's lies within the turn from s2 back to s1, with a margin). Their
/// projections then meet only at v, so the triangles do. `false` says only
/// "not shown this way".
fn sectors_apart(v: DVec3, s1: DVec3, s2: DVec3, t1: DVec3, t2: DVec3) -> bool {
    let (a1, a2, b1, b2) = (s1 - v, s2 - v, t1 - v, t2 - v);
    let (ns, nt) = (a1.cross(a2), b1.cross(b2));
    let (ls, lt) = (ns.length(), nt.length());
    if !(ls > 0.0 && lt > 0.0) {
        return false;
    }
    let axis = ns / ls + nt / lt;
    let len = axis.length();
    // nearly opposite normals: no good direction to look along
    if !(len > 0.2) {
        return false;
    }
    let axis = axis / len;
    // both face along the axis by a margin (cos 84°)
    if !(ns.dot(axis) > 0.1 * ls && nt.dot(axis) > 0.1 * lt) {
        return false;
    }
    let e1 = axis.any_orthonormal_vector();
    let e2 = axis.cross(e1);
    let flat = |d: DVec3| [d.dot(e1), d.dot(e2)];
    let (a1, a2, b1, b2) = (flat(a1), flat(a2), flat(b1), flat(b2));
    // pseudo-angles in [0, 4) from a1, counter-clockwise
    let turn = |d: [f64; 2]| {
        let p = diamond_angle(d) - diamond_angle(a1);
        if p < 0.0 { p + 4.0 } else { p }
    };
    let (ra2, rb1, rb2) = (turn(a2), turn(b1), turn(b2));
    const MARGIN: f64 = 1e-9;
    ra2 + MARGIN < rb1 && rb1 + MARGIN < rb2 && rb2 < 4.0 - MARGIN
}

/// A pseudo-angle of the 2-D direction `d`: increases with the angle,
/// [0, 4) over one turn (0, 1, 2, 3 at the axes), without trigonometry.
#[inline]
fn diamond_angle(d: [f64; 2]) -> f64 {
    let [x, y] = d;
    let s = x.abs() + y.abs();
    if !(s > 0.0) {
        return 0.0;
    }
    if y >= 0.0 {
        if x >= 0.0 { y / s } else { 1.0 - x / s }
    } else if x < 0.0 {
        2.0 - y / s
    } else {
        3.0 + x / s
    }
}

/// Whether `w` is off the plane of normal `n` (= `e × f` for the shared edge
/// `e`): `|n·w| / (|n| |e|) > 1e-9` (denominator at least `1e-300`). Compared
/// squared first; the quotient is computed only when the two are within
/// rounding of each other (the answer is the same).
#[inline]
fn off_plane(n: DVec3, e: DVec3, w: DVec3) -> bool {
    let num = n.dot(w);
    let scale = e.length_squared().max(1e-300);
    let n2 = n.length_squared();
    const SAFE: std::ops::RangeInclusive<f64> = 1e-250..=1e250;
    if SAFE.contains(&n2) && SAFE.contains(&scale) && SAFE.contains(&(n2 * scale)) {
        let (num2, lim) = (num * num, 1e-18 * (n2 * scale));
        if num2 > lim * (1.0 + 1e-9) {
            return true;
        }
        if num2 < lim * (1.0 - 1e-9) {
            return false;
        }
    }
    off_plane_reference(n, e, w)
}

/// [`off_plane`] as it was written first.
fn off_plane_reference(n: DVec3, e: DVec3, w: DVec3) -> bool {
    let scale = e.length_squared().max(1e-300);
    let off = n.dot(w) / (n.length() * scale.sqrt()).max(1e-300);
    off.abs() > 1e-9
}

/// Whether all of `t` lies strictly on one side of the plane of `s` (then they
/// cannot intersect; shared vertices lie on the plane and do not count).
///
/// A vertex of `t` is on the plane when its distance `d` (scaled by the normal
/// `n = (s1 - s0) × (s2 - s0)`) is at most `eps = 1e-12 |n| max|t_k - s0|`.
/// `d²` is first compared with `eps²` (no square roots); only when they are
/// within rounding of each other is `eps` computed (the answer is the same).
fn separated_by_plane(s: &[DVec3; 3], t: &[DVec3; 3]) -> bool {
    let n = (s[1] - s[0]).cross(s[2] - s[0]);
    let r = [t[0] - s[0], t[1] - s[0], t[2] - s[0]];
    let d = [n.dot(r[0]), n.dot(r[1]), n.dot(r[2])];
    let n2 = n.length_squared();
    let l2 = r[0]
        .length_squared()
        .max(r[1].length_squared())
        .max(r[2].length_squared());
    // side of each vertex: 1 above, -1 below, 0 on the plane
    let mut side = [0i8; 3];
    let mut decided = false;
    const SAFE: std::ops::RangeInclusive<f64> = 1e-250..=1e250;
    if SAFE.contains(&n2) && SAFE.contains(&l2) && SAFE.contains(&(n2 * l2)) {
        // eps² with a margin far above the rounding of either form
        let e2 = 1e-24 * (n2 * l2);
        let (above, below) = (e2 * (1.0 + 1e-9), e2 * (1.0 - 1e-9));
        decided = true;
        for k in 0..3 {
            let d2 = d[k] * d[k];
            if d2 > above {
                side[k] = if d[k] > 0.0 { 1 } else { -1 };
            } else if d2 >= below || d2.is_nan() {
                decided = false;
                break;
            }
        }
    }
    if !decided {
        let scale = n.length() * r[0].length().max(r[1].length()).max(r[2].length());
        let eps = 1e-12 * scale;
        side = d.map(|x| {
            if x > eps {
                1
            } else if x < -eps {
                -1
            } else {
                0
            }
        });
    }
    let pos = side.iter().filter(|&&x| x > 0).count();
    let neg = side.iter().filter(|&&x| x < 0).count();
    let zero = 3 - pos - neg;
    // vertices on the plane may be shared ones: separated if the others agree and
    // those on the plane are vertices of s
    (pos + zero == 3 && pos > 0 || neg + zero == 3 && neg > 0)
        && (0..3).all(|k| side[k] != 0 || s.contains(&t[k]))
}

/// [`separated_by_plane`] as it was written first (the reference for tests).
#[cfg(test)]
fn separated_by_plane_reference(s: &[DVec3; 3], t: &[DVec3; 3]) -> bool {
    let n = (s[1] - s[0]).cross(s[2] - s[0]);
    let scale = n.length()
        * (t[0] - s[0])
            .length()
            .max((t[1] - s[0]).length())
            .max((t[2] - s[0]).length());
    let eps = 1e-12 * scale;
    let d = t.map(|q| n.dot(q - s[0]));
    let pos = d.iter().filter(|&&x| x > eps).count();
    let neg = d.iter().filter(|&&x| x < -eps).count();
    let zero = 3 - pos - neg;
    (pos + zero == 3 && pos > 0 || neg + zero == 3 && neg > 0)
        && (0..3).all(|k| d[k].abs() > eps || s.contains(&t[k]))
}

fn disjoint_intersect(s: &[DVec3; 3], t: &[DVec3; 3]) -> bool {
    for k in 0..3 {
        if segment_hits_triangle(s[k], s[(k + 1) % 3], t)
            || segment_hits_triangle(t[k], t[(k + 1) % 3], s)
        {
            return true;
        }
    }
    coplanar_overlap(s, t)
}

/// Segment [a, b] against triangle t (closed), non-coplanar case.
fn segment_hits_triangle(a: DVec3, b: DVec3, t: &[DVec3; 3]) -> bool {
    let (e1, e2) = (t[1] - t[0], t[2] - t[0]);
    let d = b - a;
    let h = d.cross(e2);
    let det = e1.dot(h);
    let scale = e1.length() * e2.length() * d.length();
    if det.abs() <= 1e-12 * scale {
        return false; // parallel: handled by the coplanar tests
    }
    let inv = 1.0 / det;
    let sv = a - t[0];
    let u = sv.dot(h) * inv;
    let q = sv.cross(e1);
    let v = d.dot(q) * inv;
    let w = e2.dot(q) * inv;
    let eps = 1e-12;
    u >= -eps && v >= -eps && u + v <= 1.0 + eps && (-eps..=1.0 + eps).contains(&w)
}

fn normal(t: &[DVec3; 3]) -> DVec3 {
    (t[1] - t[0]).cross(t[2] - t[0])
}

fn is_coplanar(s: &[DVec3; 3], t: &[DVec3; 3]) -> bool {
    let n = normal(s);
    let len = n.length();
    if len == 0.0 {
        return false;
    }
    let size = (s[1] - s[0]).length().max((s[2] - s[0]).length());
    t.iter()
        .all(|q| (n.dot(*q - s[0]) / len).abs() <= 1e-9 * size)
}

/// Projects onto the plane of the dominant normal axis.
fn project(n: DVec3, q: DVec3) -> [f64; 2] {
    let a = n.abs();
    if a.x >= a.y && a.x >= a.z {
        [q.y, q.z]
    } else if a.y >= a.z {
        [q.x, q.z]
    } else {
        [q.x, q.y]
    }
}

fn orient2(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
}

fn segments_cross_2d(a: [f64; 2], b: [f64; 2], c: [f64; 2], d: [f64; 2]) -> bool {
    let (d1, d2) = (orient2(c, d, a), orient2(c, d, b));
    let (d3, d4) = (orient2(a, b, c), orient2(a, b, d));
    d1 * d2 < 0.0 && d3 * d4 < 0.0
}

fn point_in_triangle_2d(p: [f64; 2], t: [[f64; 2]; 3]) -> bool {
    let (a, b, c) = (
        orient2(t[0], t[1], p),
        orient2(t[1], t[2], p),
        orient2(t[2], t[0], p),
    );
    (a > 0.0 && b > 0.0 && c > 0.0) || (a < 0.0 && b < 0.0 && c < 0.0)
}

fn coplanar_overlap(s: &[DVec3; 3], t: &[DVec3; 3]) -> bool {
    if !is_coplanar(s, t) {
        return false;
    }
    let n = normal(s);
    let ps = s.map(|q| project(n, q));
    let pt = t.map(|q| project(n, q));
    for i in 0..3 {
        for j in 0..3 {
            if segments_cross_2d(ps[i], ps[(i + 1) % 3], pt[j], pt[(j + 1) % 3]) {
                return true;
            }
        }
    }
    point_in_triangle_2d(ps[0], pt) || point_in_triangle_2d(pt[0], ps)
}

/// Two triangles sharing apex `v`, coplanar, whose angular sectors overlap.
fn coplanar_wedges_overlap(v: DVec3, s1: DVec3, s2: DVec3, t1: DVec3, t2: DVec3) -> bool {
    let s = [v, s1, s2];
    let t = [v, t1, t2];
    if !is_coplanar(&s, &t) {
        return false;
    }
    let n = normal(&s);
    let ps = s.map(|q| project(n, q));
    let pt = t.map(|q| project(n, q));
    // overlap iff an edge from v of one lies strictly inside the other's sector
    let inside = |w: [[f64; 2]; 3], q: [f64; 2]| {
        let (a, b) = (orient2(w[0], w[1], q), orient2(w[0], w[2], q));
        let o = orient2(w[0], w[1], w[2]);
        if o > 0.0 {
            a > 0.0 && b < 0.0
        } else {
            a < 0.0 && b > 0.0
        }
    };
    inside(ps, pt[1])
        || inside(ps, pt[2])
        || inside(pt, ps[1])
        || inside(pt, ps[2])
        || segments_cross_2d(ps[1], ps[2], pt[1], pt[2])
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::geom::test_rng::Rng;

    /// Where `beside_plane` says two triangles around a common vertex meet
    /// only there, the tests it stands in front of say so too (the plane
    /// test with its own margin, or the far edges against each other and
    /// the coplanar overlap): on random pairs, nearly coplanar pairs and
    /// slivers.
    #[test]
    fn beside_plane_never_hides_a_crossing() {
        let mut r = Rng(79);
        let mut said_apart = 0;
        for k in 0..300_000 {
            let scale = [1e-3, 1.0, 300.0][k % 3];
            let pt =
                |r: &mut Rng| DVec3::new(r.next() - 0.5, r.next() - 0.5, r.next() - 0.5) * scale;
            let v = pt(&mut r);
            let (s1, mut s2, mut t1, mut t2) = (pt(&mut r), pt(&mut r), pt(&mut r), pt(&mut r));
            match r.below(4) {
                // a sliver: s2 almost on the line v s1
                0 => s2 = v + (s1 - v) * r.next() + (s2 - v) * 1e-9,
                // t nearly in the plane of s
                1 => {
                    let n = (s1 - v).cross(s2 - v).normalize();
                    let lift = [1e-14, 1e-12, 1e-9, 1e-6][r.below(4)] * scale;
                    t1 -= n * (n.dot(t1 - v) - lift);
                    t2 -= n * (n.dot(t2 - v) - lift * r.next());
                }
                _ => {}
            }
            if !beside_plane(v, s1, s2, t1, t2) {
                continue;
            }
            said_apart += 1;
            let s = [v, s1, s2];
            let t = [v, t1, t2];
            assert!(
                separated_by_plane(&s, &t)
                    || separated_by_plane(&t, &s)
                    || !(segment_hits_triangle(s1, s2, &t)
                        || segment_hits_triangle(t1, t2, &s)
                        || coplanar_wedges_overlap(v, s1, s2, t1, t2)),
                "{s:?} {t:?}"
            );
        }
        assert!(said_apart > 10_000, "{said_apart}");
    }

    #[test]
    fn off_plane_matches_its_reference() {
        let mut r = Rng(78);
        let mut seen = [0usize; 2];
        for k in 0..200_000 {
            let scale = [1e-3, 1.0, 300.0, 1e-160][k % 4];
            let v =
                |r: &mut Rng| DVec3::new(r.next() - 0.5, r.next() - 0.5, r.next() - 0.5) * scale;
            let (e, f, mut w) = (v(&mut r), v(&mut r), v(&mut r));
            let n = e.cross(f);
            if r.below(2) == 0 {
                // near the threshold
                let target = 1e-9 * n.length() * e.length();
                let x = [0.999_999_999, 1.0, 1.000_000_001, 1.0 + 1e-15, 0.5][r.below(5)];
                w += n * ((x * target - n.dot(w)) / n.length_squared());
            }
            let want = off_plane_reference(n, e, w);
            seen[want as usize] += 1;
            assert_eq!(off_plane(n, e, w), want, "{n:?} {e:?} {w:?}");
        }
        assert!(seen[0] > 1000 && seen[1] > 1000, "{seen:?}");
    }

    #[test]
    fn separated_by_plane_matches_its_reference() {
        let mut r = Rng(77);
        let mut seen = [0usize; 2];
        for k in 0..200_000 {
            let scale = [1e-3, 1.0, 300.0][k % 3];
            let pt = |r: &mut Rng| DVec3::new(r.next(), r.next(), r.next()) * scale;
            let s = [pt(&mut r), pt(&mut r), pt(&mut r)];
            let n = (s[1] - s[0]).cross(s[2] - s[0]);
            let mut t = [pt(&mut r), pt(&mut r), pt(&mut r)];
            // put vertices on the plane, near the threshold, or on shared vertices
            for q in t.iter_mut() {
                match r.below(6) {
                    0 => *q = s[r.below(3)],
                    1 | 2 => {
                        let d = n.dot(*q - s[0]);
                        let l = (*q - s[0]).length() * 1.5;
                        let eps = 1e-12 * n.length() * l;
                        let f = [
                            0.0,
                            0.5,
                            0.999_999_999,
                            1.0,
                            1.000_000_001,
                            2.0,
                            1.0 + 1e-12,
                        ][r.below(7)];
                        let sign = if r.next() < 0.5 { -1.0 } else { 1.0 };
                        *q += n * ((sign * f * eps - d) / n.length_squared());
                    }
                    _ => {}
                }
            }
            let want = separated_by_plane_reference(&s, &t);
            seen[want as usize] += 1;
            assert_eq!(separated_by_plane(&s, &t), want, "{s:?} {t:?}");
        }
        assert!(seen[0] > 1000 && seen[1] > 1000, "{seen:?}");
    }
}
