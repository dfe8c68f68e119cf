//! The preprocessing guarantee on every small configuration: after fattening, no
//! label is critical anywhere on the mixed grid (B-K §2.1, checked exhaustively).

use septa::config::Resolved;
use septa::preprocess::preprocess;
use septa::volume::{Dims, Geometry, LabelVolume};

/// All restricted growth strings of length n with at most `max_blocks` blocks
/// (= set partitions of n cells).
fn set_partitions(n: usize, max_blocks: usize) -> Vec<Vec<u8>> {
    let mut out = Vec::new();
    let mut a = vec![0u8; n];
    fn rec(i: usize, max: u8, a: &mut Vec<u8>, max_blocks: usize, out: &mut Vec<Vec<u8>>) {
        if i == a.len() {
            out.push(a.clone());
            return;
        }
        for v in 0..=(max + 1).min(max_blocks as u8 - 1) {
            a[i] = v;
            rec(i + 1, max.max(v), a, max_blocks, out);
        }
    }
    a[0] = 0;
    rec(1, 0, &mut a, max_blocks, &mut out);
    out
}

/// Embeds a block of labels in a one-voxel margin of background label 0.
fn embed(block: [usize; 3], labels: &[i64]) -> LabelVolume {
    let dims = Dims::new(block[0] + 2, block[1] + 2, block[2] + 2).unwrap();
    let mut v = vec![0i64; dims.len()];
    for z in 0..block[2] {
        for y in 0..block[1] {
            for x in 0..block[0] {
                v[dims.index(x + 1, y + 1, z + 1)] = labels[x + block[0] * (y + block[1] * z)];
            }
        }
    }
    LabelVolume::from_values(dims, &v, Geometry::identity()).unwrap()
}

/// Runs every partition with labels 1.. (and with the first block as
/// background 0), under ascending and descending dominance; returns cases run.
fn run_all(block: [usize; 3], max_blocks: usize) -> usize {
    let n = block[0] * block[1] * block[2];
    let parts = set_partitions(n, max_blocks);
    use rayon::prelude::*;
    type Failure = (Vec<i64>, bool, septa::preprocess::Violation);
    let results: Vec<(usize, Vec<Failure>)> =
        parts.par_iter().map(|p| run_partition(block, p)).collect();
    let cases = results.iter().map(|r| r.0).sum();
    let failures: Vec<_> = results.into_iter().flat_map(|r| r.1).collect();
    assert!(
        failures.is_empty(),
        "{} of {cases} cases fail, first: {:?}",
        failures.len(),
        &failures[..failures.len().min(5)]
    );
    cases
}

fn run_partition(
    block: [usize; 3],
    p: &[u8],
) -> (usize, Vec<(Vec<i64>, bool, septa::preprocess::Violation)>) {
    let mut cases = 0;
    let mut failures = Vec::new();
    {
        for background_first in [false, true] {
            let labels: Vec<i64> = p
                .iter()
                .map(|&b| {
                    if background_first {
                        b as i64
                    } else {
                        b as i64 + 1
                    }
                })
                .collect();
            let vol = embed(block, &labels);
            for descending in [false, true] {
                let mut r = Resolved::defaults(&vol);
                r.outside = vol.id_of(0).unwrap();
                if descending {
                    let k = r.rank.len() as u32;
                    r.rank = (0..k).map(|i| k - 1 - i).collect();
                }
                let out = preprocess(&vol, &r);
                cases += 1;
                if !out.guarantee.passed() {
                    failures.push((
                        labels.clone(),
                        descending,
                        out.guarantee.first_violations[0],
                    ));
                }
            }
        }
    }
    (cases, failures)
}

#[test]
fn every_2x2x2_partition() {
    assert_eq!(set_partitions(8, 8).len(), 4140);
    assert_eq!(run_all([2, 2, 2], 8), 4140 * 4);
}

#[test]
fn every_2x2x3_with_up_to_3_labels() {
    // S(12,1) + S(12,2) + S(12,3) = 1 + 2047 + 86526
    assert_eq!(set_partitions(12, 3).len(), 88574);
    assert_eq!(run_all([2, 2, 3], 3), 88574 * 4);
}
