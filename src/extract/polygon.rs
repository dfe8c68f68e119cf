//! Decomposition of VESTA N-cycles into triangles.
//!
//! - **L** (low resolution, no extra points): the triangulation of the cycle's
//!   own points with the smallest total area that has no degenerate triangle
//!   (dynamic programming over the polygon, O(N³) for N ≤ 14). Cycles through a
//!   junction vertex are fanned from that vertex instead, which is always valid.
//! - **H** (high resolution): a fan around the average of the cycle's points
//!   (VESTA's "average point"), falling back to L where the fan would have a
//!   degenerate triangle.

use glam::DVec3;

use crate::geom::predicates::is_degenerate;

/// Minimum-area triangulation of a closed polygon without degenerate triangles.
/// Returns triangles as index triples in the polygon's orientation, or `None`
/// when every triangulation has a degenerate triangle.
pub fn min_area_triangulation(p: &[DVec3]) -> Option<Vec<[usize; 3]>> {
    let n = p.len();
    if n < 3 {
        return None;
    }
    if n == 3 {
        return (!is_degenerate(p[0], p[1], p[2])).then(|| vec![[0, 1, 2]]);
    }
    // cost[i][j]: best triangulation of the sub-polygon i..=j (j - i >= 2).
    let inf = f64::INFINITY;
    let mut cost = vec![inf; n * n];
    let mut split = vec![usize::MAX; n * n];
    for i in 0..n - 1 {
        cost[i * n + i + 1] = 0.0;
    }
    for len in 2..n {
        for i in 0..n - len {
            let j = i + len;
            for k in i + 1..j {
                if is_degenerate(p[i], p[k], p[j]) {
                    continue;
                }
                let area = 0.5 * (p[k] - p[i]).cross(p[j] - p[i]).length();
                let c = cost[i * n + k] + cost[k * n + j] + area;
                // strict improvement keeps the lowest k on ties: deterministic
                if c < cost[i * n + j] - 1e-12 {
                    cost[i * n + j] = c;
                    split[i * n + j] = k;
                }
            }
        }
    }
    if !cost[n - 1].is_finite() {
        return None;
    }
    let mut out = Vec::with_capacity(n - 2);
    let mut stack = vec![(0, n - 1)];
    while let Some((i, j)) = stack.pop() {
        if j - i < 2 {
            continue;
        }
        let k = split[i * n + j];
        out.push([i, k, j]);
        stack.push((i, k));
        stack.push((k, j));
    }
    out.sort_unstable();
    Some(out)
}

/// Fan around the polygon's average point (index `n` stands for that point).
/// `None` if a fan triangle would be degenerate.
pub fn centroid_fan(p: &[DVec3]) -> Option<(DVec3, Vec<[usize; 3]>)> {
    let n = p.len();
    let c = p.iter().copied().sum::<DVec3>() / n as f64;
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let j = (i + 1) % n;
        if is_degenerate(c, p[i], p[j]) {
            return None;
        }
        out.push([n, i, j]);
    }
    Some((c, out))
}

/// Fan from polygon vertex `apex` (valid when no fan triangle is degenerate).
pub fn vertex_fan(n: usize, apex: usize) -> Vec<[usize; 3]> {
    (1..n - 1)
        .map(|k| [apex, (apex + k) % n, (apex + k + 1) % n])
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn square_and_collinear() {
        let sq = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        ];
        let t = min_area_triangulation(&sq).unwrap();
        assert_eq!(t.len(), 2);
        // a polygon with three collinear points must avoid the flat triangle
        let p = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
        ];
        let t = min_area_triangulation(&p).unwrap();
        for tri in &t {
            assert!(!is_degenerate(p[tri[0]], p[tri[1]], p[tri[2]]));
        }
        assert_eq!(t.len(), 2);
        let (_, fan) = centroid_fan(&sq).unwrap();
        assert_eq!(fan.len(), 4);
        assert_eq!(vertex_fan(5, 2), vec![[2, 3, 4], [2, 4, 0], [2, 0, 1]]);
    }
}
