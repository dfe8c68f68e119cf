//! Run-time CPU dispatch of the hot loops (x86_64 only: elsewhere the plain
//! bodies run).
//!
//! septa builds for baseline x86-64, where `u64::count_ones` is a dozen
//! instructions instead of one `popcnt`, `trailing_zeros` needs a zero check
//! and the comparisons of the activity pass run on 128-bit vectors. The hot
//! loops of the iso-surface are therefore `#[inline(always)]` bodies behind two
//! entry points each: the plain body, and an `unsafe fn` with
//! `#[target_feature(enable = "popcnt,bmi1,bmi2,lzcnt,avx2")]` (what every
//! x86-64 CPU since about 2013–2015 has: x86-64-v3 without FMA and MOVBE) that
//! calls it, taken when [`fast`] says the running CPU has those features. No
//! floating-point operation changes with them (FMA is not among them, and Rust
//! never contracts `a * b + c`), so both entry points give bit-identical
//! results.

use std::sync::OnceLock;

/// Whether the fast entry points may run: the running CPU has their features
/// and the environment variable `SEPTA_PORTABLE` is not set (it forces the
/// plain code, for tests). Checked once per process.
#[inline]
pub(crate) fn fast() -> bool {
    static FAST: OnceLock<bool> = OnceLock::new();
    *FAST.get_or_init(|| std::env::var_os("SEPTA_PORTABLE").is_none() && detect())
}

fn detect() -> bool {
    std::is_x86_feature_detected!("popcnt")
        && std::is_x86_feature_detected!("bmi1")
        && std::is_x86_feature_detected!("bmi2")
        && std::is_x86_feature_detected!("lzcnt")
        && std::is_x86_feature_detected!("avx2")
}
