//! Which cells (triangles, tetrahedra) hold each vertex, as compressed rows.

/// The cells of `cells` around each of `n` vertices: row `v` is
/// `list[start[v]..start[v + 1]]`, cell ids in increasing order.
///
/// ```
/// let (start, list) = septa::geom::incidence::rows(4, &[[0, 1, 2], [0, 2, 3]]);
/// assert_eq!(&list[start[0] as usize..start[1] as usize], &[0, 1]);
/// assert_eq!(&list[start[3] as usize..start[4] as usize], &[1]);
/// ```
pub fn rows<const K: usize>(n: usize, cells: &[[u32; K]]) -> (Vec<u32>, Vec<u32>) {
    let mut start = vec![0u32; n + 1];
    for c in cells {
        for &v in c {
            start[v as usize + 1] += 1;
        }
    }
    for v in 0..n {
        start[v + 1] += start[v];
    }
    let mut fill = start.clone();
    let mut list = vec![0u32; start[n] as usize];
    for (i, c) in cells.iter().enumerate() {
        for &v in c {
            list[fill[v as usize] as usize] = i as u32;
            fill[v as usize] += 1;
        }
    }
    (start, list)
}
