//! Every 2×2×2 configuration (all 4140 set partitions, with labels 1.. and with
//! the first block as background) and random volumes from smooth blobs to pure
//! noise, with and without separation constraints: preprocess, extract with
//! every surface/decomposition, validate every output.

mod common;

use common::*;
use proptest::prelude::*;
use rayon::prelude::*;
use septa::config::SeparationIds;

fn set_partitions(n: usize) -> Vec<Vec<u8>> {
    fn rec(i: usize, max: u8, a: &mut Vec<u8>, out: &mut Vec<Vec<u8>>) {
        if i == a.len() {
            out.push(a.clone());
            return;
        }
        for v in 0..=max + 1 {
            a[i] = v;
            rec(i + 1, max.max(v), a, out);
        }
    }
    let mut out = Vec::new();
    let mut a = vec![0u8; n];
    rec(1, 0, &mut a, &mut out);
    out
}

#[test]
fn every_2x2x2_partition_extracts_valid_patches() {
    let parts = set_partitions(8);
    assert_eq!(parts.len(), 4140);
    let failures: Vec<String> = parts
        .par_iter()
        .flat_map_iter(|p| {
            let mut fails = Vec::new();
            for shift in [1i64, 0] {
                let mut v = vec![0i64; 64];
                for (i, &b) in p.iter().enumerate() {
                    let (x, y, z) = (i % 2, i / 2 % 2, i / 4);
                    v[(x + 1) + 4 * ((y + 1) + 4 * (z + 1))] = b as i64 + shift;
                }
                let (vol, r) = resolved_outside0(volume([4, 4, 4], &v));
                // labels 1.. in background: VESTA L, faces and VESTA L with flat
                // stretches merged; background inside: VESTA H
                let picks = if shift == 1 { [0, 2, 4] } else { [1, 1, 1] };
                for opts in picks
                    .map(|i| all_options()[i])
                    .into_iter()
                    .take(if shift == 1 { 3 } else { 1 })
                {
                    let (_, _, rep) = run(&vol, &r, opts);
                    if !rep.passed() {
                        fails.push(format!("{p:?} shift {shift} {opts:?}:\n{}", rep.summary()));
                    }
                }
            }
            fails
        })
        .collect();
    assert!(
        failures.is_empty(),
        "{} failures, first:\n{}",
        failures.len(),
        failures[0]
    );
}

/// A random volume: `mode` 0 = pure noise, 1 = blobs, 2 = smooth bands.
fn random_volume(dims: [usize; 3], labels: u64, mode: u8, seed: u64) -> Vec<i64> {
    let mut rng = Rng(seed);
    let n = dims[0] * dims[1] * dims[2];
    match mode {
        0 => (0..n).map(|_| rng.below(labels) as i64).collect(),
        1 => {
            let mut v = vec![0i64; n];
            for _ in 0..6 {
                let c = [0, 1, 2].map(|a| (rng.below(dims[a] as u64 * 10) as f64) / 10.0);
                let r = 0.5 + (rng.below(30) as f64) / 10.0;
                let l = rng.below(labels) as i64;
                for (i, val) in v.iter_mut().enumerate() {
                    let p = [i % dims[0], i / dims[0] % dims[1], i / (dims[0] * dims[1])]
                        .map(|x| x as f64);
                    if (0..3).map(|a| (p[a] - c[a]).powi(2)).sum::<f64>() <= r * r {
                        *val = l;
                    }
                }
            }
            v
        }
        _ => {
            let f = [0, 1, 2].map(|_| 0.2 + rng.below(100) as f64 / 80.0);
            (0..n)
                .map(|i| {
                    let p = [i % dims[0], i / dims[0] % dims[1], i / (dims[0] * dims[1])]
                        .map(|x| x as f64);
                    let s = (p[0] * f[0]).sin()
                        + (p[1] * f[1]).cos()
                        + (p[2] * f[2] + p[0] * 0.3).sin();
                    (((s + 3.0) / 6.0 * labels as f64) as i64).clamp(0, labels as i64 - 1)
                })
                .collect()
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, .. ProptestConfig::default() })]

    #[test]
    fn random_volumes_extract_valid_patches(
        nx in 1usize..9, ny in 1usize..9, nz in 1usize..9,
        labels in 2u64..9, mode in 0u8..3, seed in any::<u64>(), constrain in any::<bool>(),
    ) {
        let v = random_volume([nx, ny, nz], labels, mode, seed);
        let vol = volume([nx, ny, nz], &v);
        let vol = if constrain { septa::config::with_extra_values(vol, &[1, 2, 3]) } else { vol };
        let (vol, mut r) = resolved_outside0(vol);
        if constrain {
            // labels 1 and 2 must be separated by 3
            r.separations = vec![SeparationIds { labels: vec![vol.id_of(1).unwrap(), vol.id_of(2).unwrap()], by: vol.id_of(3).unwrap() }];
        }
        for opts in all_options() {
            let (pre, mesh, rep) = run(&vol, &r, opts);
            prop_assert!(pre.guarantee.passed(), "{:?}", pre.guarantee);
            prop_assert!(rep.passed(), "{opts:?}\n{}", rep.summary());
            for sep in &r.separations {
                prop_assert!(mesh.patch_of(sep.labels[0], sep.labels[1]).is_none(), "constrained pair has a patch");
            }
        }
    }
}
