//! The working mesh of the remesher and its domain decomposition.
//!
//! Between passes the mesh is one vertex pool for all patches ([`Work`]).
//! A pass cuts space into columns ([`Blocks`]) over a grid in the plane of
//! the mesh's two longest axes; every triangle belongs to the block holding
//! its centroid. Blocks of one colour (same parity of both grid indices:
//! four colours) are remeshed in parallel, largest first, each by its own
//! [`Remesher`] over its triangles, with the vertices it shares with other
//! blocks locked and the triangles of the neighbouring blocks beside it as
//! fixed obstacles of its crossing guard. Blocks of one colour are a whole
//! block apart along at least one axis, wider than anything an operation can
//! reach, so no two of them touch the same triangle or see each other's; the
//! result does not depend on the number of threads. The other colours
//! follow, then the next iteration with the block borders moved by half a
//! block. A block's pass also takes the triangles of its neighbours of later
//! colours within a halo of its border ([`Blocks::pass_block`]), so the
//! vertices on every border are free in one pass of each iteration: seams
//! locked for a whole iteration cost a share of the edges in range (MNI152:
//! 97.4 % with them, 97.9 % without, at 8 iterations). (Slabs along one
//! axis, the earlier design, left two or three busy slabs per colour on real
//! heads: one thread idle half the time.)

use glam::DVec3;
use hashbrown::HashMap;
use rayon::prelude::*;

use super::isotropic::{CurveRun, Region, RegionPatch, RegionResult, Remesher};
use super::network::VertexKind;
use super::sizing::Sizing;
use crate::geom::dsu::Dsu;
use crate::geom::nearest::{CurveRef, SurfaceRef};

/// The mesh being remeshed: one vertex pool, triangles with their patch, a
/// hint into the patch's reference, whether they are unchanged since the
/// extraction, the label surface components on their two sides and their
/// block in this iteration;
/// the junction curves over the pool.
#[derive(Clone, Debug)]
pub(super) struct Work {
    pub(super) pos: Vec<DVec3>,
    pub(super) kind: Vec<VertexKind>,
    pub(super) tris: Vec<[u32; 3]>,
    pub(super) patch: Vec<u32>,
    /// Per patch: its two label ids (the normals point from the first into
    /// the second).
    labels: Vec<[u32; 2]>,
    pub(super) hint: Vec<u32>,
    pub(super) kept: Vec<bool>,
    /// Per triangle: the components of the label surfaces on its two sides
    /// (see [`label_surface_components`]). Found once: no operation joins,
    /// cuts or opens a component, and the triangles an operation makes
    /// take the components of those they replace.
    component: Vec<Sides>,
    /// Per component: its signed enclosed volume, kept up to date with
    /// what every block's operations changed (summed in block order).
    volume: Vec<f64>,
    /// Per component: a point near it, about which its volume is
    /// summed (the sum over a closed surface does not depend on the
    /// origin, and a near one keeps it precise).
    origin: Vec<DVec3>,
    /// Per triangle: the block holding its centroid, of the blocks given to
    /// [`Work::assign_blocks`] (the triangles a pass makes are assigned as
    /// they are made).
    block: Vec<u32>,
    pub(super) curves: Vec<Vec<u32>>,
    pub(super) closed: Vec<bool>,
}

/// What every slab's remesher shares (read only).
pub(super) struct Shared<'r> {
    pub(super) references: &'r [SurfaceRef],
    pub(super) curve_references: &'r [CurveRef],
    pub(super) sizing: &'r Sizing,
    /// Largest distance of a new triangle's centroid from the reference (mm).
    pub(super) eps: f64,
    /// Whether this pass's relaxation moves vertices off the reference so
    /// that the triangles lie on it on average (see
    /// `isotropic::chord_offset`): those of the last two iterations.
    pub(super) offset_chords: bool,
    /// Per patch: how far off the reference (along its normal, mm) its
    /// vertices sit in the offset iterations, on top of their chord offsets,
    /// so that every label keeps its volume (see `volume`).
    pub(super) patch_offsets: Vec<f64>,
}

/// The blocks of one pass: columns over a grid in the plane of the mesh's
/// two longest axes (borders at `origin[k] + i · width[k]` along `axes[k]`),
/// each spanning the third axis whole. Block `(i, j)` is number `i + count[0]
/// · j` and has colour `i % 2 + 2 · (j % 2)`: two blocks of one colour are a
/// whole block apart along at least one axis.
#[derive(Clone, Copy, Debug)]
pub(super) struct Blocks {
    pub(super) axes: [usize; 2],
    pub(super) origin: [f64; 2],
    pub(super) width: [f64; 2],
    pub(super) count: [usize; 2],
    /// How far beyond its block an operation may make triangles (mm).
    pub(super) reach: f64,
    /// How far a block's pass reaches into its neighbours of later colours
    /// (mm; see [`Blocks::pass_block`]).
    pub(super) halo: f64,
}

/// Blocks along each of the two longest axes of the work: enough to keep two
/// threads busy (9 to 16 blocks per colour), few enough that little of the
/// surface lies in the halos, which two passes remesh. (Measured with halos,
/// one thread, against 6: 5 per axis takes the same CPU on the head and
/// MNI152, 4 per axis 5 % less on MNI152 but leaves two threads unevenly
/// loaded.)
pub(super) const BLOCKS_PER_AXIS: f64 = 6.0;

/// Colours of [`Blocks`]: blocks of one colour are remeshed at the same time.
pub(super) const COLOURS: usize = 4;

impl Blocks {
    /// Blocks over `work`'s extent at least `min_width` wide (and at most
    /// about [`BLOCKS_PER_AXIS`] per axis), shifted by `shift` block widths.
    pub(super) fn over(work: &Work, min_width: f64, reach: f64, halo: f64, shift: f64) -> Blocks {
        let (lo, hi) = work.pos.iter().fold(
            (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN)),
            |(lo, hi), p| (lo.min(*p), hi.max(*p)),
        );
        let ext = (hi - lo).max(DVec3::ZERO);
        let mut order = [0, 1, 2];
        order.sort_by(|&a, &b| ext[b].total_cmp(&ext[a]));
        let axes = [order[0], order[1]];
        let width = axes.map(|a| (ext[a] / BLOCKS_PER_AXIS).max(min_width).max(1e-9));
        let origin = [0, 1].map(|k| lo[axes[k]] - width[k] * shift.fract());
        let count =
            [0, 1].map(|k| (((hi[axes[k]] - origin[k]) / width[k]).floor() as usize + 1).max(1));
        Blocks {
            axes,
            origin,
            width,
            count,
            reach,
            halo,
        }
    }

    /// How many blocks there are.
    pub(super) fn len(&self) -> usize {
        self.count[0] * self.count[1]
    }

    /// Index along grid axis `k` of the block holding coordinate `x`.
    #[inline]
    fn index_along(&self, k: usize, x: f64) -> usize {
        let i = ((x - self.origin[k]) / self.width[k]).floor();
        if i.is_nan() || i < 0.0 {
            0
        } else {
            (i as usize).min(self.count[k] - 1)
        }
    }

    /// The block holding point `p`.
    #[inline]
    fn of(&self, p: DVec3) -> usize {
        let i = self.index_along(0, p[self.axes[0]]);
        let j = self.index_along(1, p[self.axes[1]]);
        i + self.count[0] * j
    }

    /// Grid coordinates of block `b`.
    #[inline]
    fn coords(&self, b: usize) -> [usize; 2] {
        [b % self.count[0], b / self.count[0]]
    }

    fn colour(&self, b: usize) -> usize {
        let [i, j] = self.coords(b);
        i % 2 + 2 * (j % 2)
    }

    /// Border `i` along grid axis `k` (between blocks `i - 1` and `i`).
    fn bound(&self, k: usize, i: usize) -> f64 {
        self.origin[k] + i as f64 * self.width[k]
    }

    /// The block whose pass of colour `colour` remeshes a triangle of block
    /// `own` with centroid `p`: the block of that colour next to `own` if
    /// `own`'s colour comes later and `p` lies within the halo of their
    /// border, else `own`. So each pass also takes a strip of the neighbours
    /// that have not had theirs yet, and the vertices on its block's border,
    /// shared with those neighbours, are free in it: no seam stays locked
    /// through an iteration (the vertices locked at the strip's far side are
    /// inside the neighbour, free in its pass). Two blocks of one colour are
    /// a block apart, wider than two halos and two reaches, so their passes
    /// still never meet.
    fn pass_block(&self, p: DVec3, own: usize, colour: usize) -> usize {
        if self.colour(own) <= colour || self.halo <= 0.0 {
            return own;
        }
        let c = self.coords(own);
        let mut at = c;
        for k in 0..2 {
            if c[k] % 2 == (colour >> k) % 2 {
                continue;
            }
            // the neighbour along this axis with the parity the colour has
            let x = p[self.axes[k]];
            if c[k] > 0 && x - self.bound(k, c[k]) < self.halo {
                at[k] = c[k] - 1;
            } else if c[k] + 1 < self.count[k] && self.bound(k, c[k] + 1) - x < self.halo {
                at[k] = c[k] + 1;
            } else {
                return own;
            }
        }
        at[0] + self.count[0] * at[1]
    }

    /// The blocks next to block `b` (sharing a side or a corner).
    fn neighbours(&self, b: usize) -> impl Iterator<Item = usize> + '_ {
        let [i, j] = self.coords(b);
        (-1i64..=1)
            .flat_map(move |dj| (-1i64..=1).map(move |di| (di, dj)))
            .filter(|&d| d != (0, 0))
            .filter_map(move |(di, dj)| {
                let (ni, nj) = (i as i64 + di, j as i64 + dj);
                (ni >= 0
                    && nj >= 0
                    && (ni as usize) < self.count[0]
                    && (nj as usize) < self.count[1])
                    .then(|| ni as usize + self.count[0] * nj as usize)
            })
    }

    /// The box in which block `b`'s operations may make triangles: the block
    /// grown by its halo and the reach (unbounded along the third axis).
    fn trusted(&self, b: usize) -> (DVec3, DVec3) {
        let c = self.coords(b);
        let mut lo = DVec3::splat(f64::NEG_INFINITY);
        let mut hi = DVec3::splat(f64::INFINITY);
        for k in 0..2 {
            lo[self.axes[k]] = self.bound(k, c[k]) - self.halo - self.reach;
            hi[self.axes[k]] = self.bound(k, c[k] + 1) + self.halo + self.reach;
        }
        (lo, hi)
    }
}

/// `work` of each item of `todo` (sorted largest first), in the order of
/// `todo`. Each thread takes the next item when it is free, so the largest
/// blocks start first and the small ones fill the gaps at the end (rayon's
/// halving of the list gave one thread the largest half of a colour's
/// blocks). Which thread runs an item changes nothing in its result.
pub(super) fn largest_first<T: Send>(todo: &[usize], work: impl Fn(usize) -> T + Sync) -> Vec<T> {
    let next = std::sync::atomic::AtomicUsize::new(0);
    let threads = rayon::current_num_threads().min(todo.len()).max(1);
    let mut done: Vec<(usize, T)> = (0..threads)
        .into_par_iter()
        .with_max_len(1)
        .flat_map_iter(|_| {
            std::iter::from_fn(|| {
                let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                todo.get(i).map(|&b| (i, work(b)))
            })
            .collect::<Vec<_>>()
        })
        .collect();
    done.sort_unstable_by_key(|&(i, _)| i);
    done.into_iter().map(|(_, t)| t).collect()
}

/// `work` of every item `0..n`, the largest (by `size`) started first
/// ([`largest_first`]), results in item order.
pub(super) fn by_size_largest_first<T: Send>(
    n: usize,
    size: impl Fn(usize) -> usize,
    work: impl Fn(usize) -> T + Sync,
) -> Vec<T> {
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by_key(|&i| std::cmp::Reverse(size(i)));
    let mut done: Vec<(usize, T)> = order
        .iter()
        .copied()
        .zip(largest_first(&order, work))
        .collect();
    done.sort_unstable_by_key(|&(i, _)| i);
    done.into_iter().map(|(_, t)| t).collect()
}

/// What one slab's remeshing gives back, over global ids: `NEW + i` for the
/// i-th vertex it made.
struct Outcome {
    stats: [u64; 10],
    moved: Vec<(u32, DVec3)>,
    dead: Vec<u32>,
    /// Vertices made here: position, kind, and whether still in use (a
    /// vertex made by a split may be collapsed away in the same pass).
    made: Vec<(DVec3, VertexKind, bool)>,
    triangles: Vec<OutcomeTriangle>,
    /// Per curve run: its curve and what became of it.
    runs: Vec<(u32, RunResult)>,
    /// Per component changed here: the volume it gained.
    volume_changes: Vec<(u32, f64)>,
}

/// A triangle of an [`Outcome`], over global ids.
struct OutcomeTriangle {
    vertices: [u32; 3],
    patch: u32,
    hint: u32,
    kept: bool,
    component: Sides,
    /// The block holding its centroid.
    block: u32,
}

const NEW: u32 = 1 << 31;

/// No component (see [`ClosedComponents`]).
const NONE_COMPONENT: u32 = u32::MAX;

/// The label surface components on a triangle's two sides: `[0]` that of
/// its patch's first label (behind it: the normal points away from it),
/// `[1]` that of the second (in front), each an index into the components
/// or [`NONE_COMPONENT`].
pub(super) type Sides = [u32; 2];

/// No local id (in [`LOCAL_IDS`]).
pub(super) const NO_LOCAL: u32 = u32::MAX;

thread_local! {
    /// Per worker thread: the local id of each global vertex in the block
    /// being gathered, [`NO_LOCAL`] everywhere else between blocks. Kept from
    /// block to block: a hash map per block cost more than the rest of the
    /// gathering (taken out while in use, so a block started on this thread
    /// meanwhile makes its own).
    static LOCAL_IDS: LocalTable = const { std::cell::Cell::new(Vec::new()) };
    /// Likewise, the local index of each label surface component.
    static LOCAL_COMPONENTS: LocalTable = const { std::cell::Cell::new(Vec::new()) };
}

/// A per-thread table of local ids (see [`LOCAL_IDS`]).
type LocalTable = std::cell::Cell<Vec<u32>>;

/// This thread's `table` ([`NO_LOCAL`] everywhere), for `n` global ids;
/// give it back with [`return_table`].
fn take_table(table: &'static std::thread::LocalKey<LocalTable>, n: usize) -> Vec<u32> {
    let mut local = table.with(|c| c.take());
    if local.len() < n {
        local.resize(n, NO_LOCAL);
    }
    local
}

/// Gives `table` back to this thread, with the entries of the global ids
/// `used` (the only ones set) back to [`NO_LOCAL`].
fn return_table(
    table: &'static std::thread::LocalKey<LocalTable>,
    mut local: Vec<u32>,
    used: &[u32],
) {
    for &g in used {
        local[g as usize] = NO_LOCAL;
    }
    table.with(|c| c.set(local));
}

/// This thread's table of local vertex ids ([`NO_LOCAL`] everywhere), for
/// `n` global vertices; give it back with [`return_local_ids`].
pub(super) fn take_local_ids(n: usize) -> Vec<u32> {
    take_table(&LOCAL_IDS, n)
}

/// Gives the table back to this thread, with the entries of the global
/// vertices `used` (the only ones set) back to [`NO_LOCAL`].
pub(super) fn return_local_ids(local: Vec<u32>, used: &[u32]) {
    return_table(&LOCAL_IDS, local, used);
}

/// Per label surface component of the working mesh ([`Work::component`]):
/// the share of its signed enclosed volume each slab of a pass may use (its
/// volume over the number of slabs of the pass holding it, so that together
/// they cannot take it past zero).
struct ClosedComponents {
    share: Vec<f64>,
}

/// A remeshed curve run: it covered the old vertices `start ..= start +
/// edges` of its curve (cyclically on a closed one; `whole`: the entire
/// closed curve) and has these vertices now (the same two ends).
struct RunResult {
    start: usize,
    edges: usize,
    whole: bool,
    vertices: Vec<u32>,
}

impl Work {
    /// The working mesh over vertices `pos` (of kinds `kind`) and triangles
    /// `tris` (of patches `patch`, with reference hints `hint`), all as
    /// extracted, the label ids of each patch (`labels`: the normals point
    /// from the first into the second) and the junction curves (vertex
    /// lists, closed or not).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn new(
        pos: Vec<DVec3>,
        kind: Vec<VertexKind>,
        tris: Vec<[u32; 3]>,
        patch: Vec<u32>,
        labels: Vec<[u32; 2]>,
        hint: Vec<u32>,
        curves: Vec<Vec<u32>>,
        closed: Vec<bool>,
    ) -> Self {
        let (component, origin) = label_surface_components(&pos, &kind, &tris, &patch, &labels);
        let volume = component_volumes(&pos, &tris, &component, &origin);
        Work {
            kept: vec![true; tris.len()],
            block: vec![0; tris.len()],
            pos,
            kind,
            tris,
            patch,
            labels,
            hint,
            component,
            volume,
            origin,
            curves,
            closed,
        }
    }

    /// Puts every triangle in the block of `blocks` holding its centroid
    /// (the blocks of the passes that follow).
    pub(super) fn assign_blocks(&mut self, blocks: &Blocks) {
        let pos = &self.pos;
        self.block = self
            .tris
            .par_iter()
            .map(|t| blocks.of(centroid(pos, t)) as u32)
            .collect();
    }

    /// How many triangles use each vertex.
    fn vertex_uses(&self) -> Vec<u32> {
        use std::sync::atomic::{AtomicU32, Ordering};
        let uses: Vec<AtomicU32> = (0..self.pos.len()).map(|_| AtomicU32::new(0)).collect();
        self.tris.par_iter().with_min_len(1 << 14).for_each(|t| {
            for &v in t {
                uses[v as usize].fetch_add(1, Ordering::Relaxed);
            }
        });
        uses.into_iter().map(AtomicU32::into_inner).collect()
    }

    /// One remeshing iteration of every block of colour `colour` (below
    /// [`COLOURS`]) of `blocks`, the blocks last given to [`Work::assign_blocks`].
    pub(super) fn pass(&mut self, blocks: &Blocks, colour: usize, shared: &Shared) {
        let t_pass = std::time::Instant::now();
        debug_assert_eq!(self.block.len(), self.tris.len(), "blocks assigned");
        if blocks.halo > 0.0 {
            // (a triangle taken into a halo comes back, remeshed, with the
            // block of its centroid)
            let pos = &self.pos;
            self.block
                .par_iter_mut()
                .zip(&self.tris)
                .with_min_len(1 << 14)
                .for_each(|(b, t)| {
                    *b = blocks.pass_block(centroid(pos, t), *b as usize, colour) as u32;
                });
        }
        let mut buckets: Vec<Vec<u32>> = vec![Vec::new(); blocks.len()];
        for (t, &s) in self.block.iter().enumerate() {
            buckets[s as usize].push(t as u32);
        }
        let uses = self.vertex_uses();
        // largest blocks first, one per task: the threads stay busy
        let mut todo: Vec<usize> = (0..blocks.len())
            .filter(|&b| blocks.colour(b) == colour && !buckets[b].is_empty())
            .collect();
        todo.sort_by_key(|&b| std::cmp::Reverse(buckets[b].len()));
        let closed = self.closed_component_shares(&todo, &buckets);
        let t_pre = t_pass.elapsed();
        let outcomes = largest_first(&todo, |b| {
            self.remesh_block(blocks, b, &buckets, &uses, &closed, shared)
        });
        if std::env::var_os("SEPTA_DEBUG_ITER").is_some() {
            let mut t = [0u64; 10];
            for o in &outcomes {
                for k in 0..10 {
                    t[k] += o.stats[k];
                }
            }
            let per: Vec<String> = todo
                .iter()
                .zip(&outcomes)
                .map(|(&s, o)| {
                    format!(
                        "{}:{}k/{}ms",
                        s,
                        buckets[s].len() / 1000,
                        o.stats[9] / 1_000_000
                    )
                })
                .collect();
            eprintln!("  slabs {}", per.join(" "));
            eprintln!("  pre {:?}, blocks {:?}", t_pre, t_pass.elapsed() - t_pre);
            eprintln!(
                "  colour {colour}: {} guard queries ({:.1} made each, {:.1} µs each, {} refused); ms: curves {}, split {}, collapse {}, flip {}, relax {}, slab total {}",
                t[0],
                t[1] as f64 / t[0].max(1) as f64,
                t[2] as f64 / t[0].max(1) as f64 / 1000.0,
                t[3],
                t[4] / 1_000_000,
                t[5] / 1_000_000,
                t[6] / 1_000_000,
                t[7] / 1_000_000,
                t[8] / 1_000_000,
                t[9] / 1_000_000
            );
        }
        let t_m = std::time::Instant::now();
        self.merge(&todo, outcomes);
        if std::env::var_os("SEPTA_DEBUG_ITER").is_some() {
            eprintln!("  merge {:?}", t_m.elapsed());
        }
        if cfg!(debug_assertions) || std::env::var_os("SEPTA_DEBUG_WORK").is_some() {
            if let Err(e) = self.check() {
                panic!("after pass colour {colour} over {blocks:?}: {e}");
            }
        }
    }

    /// The share of its signed volume that each slab of `todo` may use, per
    /// label surface component.
    fn closed_component_shares(&self, todo: &[usize], buckets: &[Vec<u32>]) -> ClosedComponents {
        let volume = &self.volume;
        // slabs of this colour holding each component
        let mut slabs = vec![0u32; volume.len()];
        let mut last = vec![usize::MAX; volume.len()];
        for &s in todo {
            for &t in &buckets[s] {
                for c in self.component[t as usize] {
                    if c != NONE_COMPONENT && last[c as usize] != s {
                        last[c as usize] = s;
                        slabs[c as usize] += 1;
                    }
                }
            }
        }
        let share = volume
            .iter()
            .zip(&slabs)
            .map(|(v, &k)| v / k.max(1) as f64)
            .collect();
        ClosedComponents { share }
    }

    /// Every patch a manifold: each directed edge once per patch; the
    /// label surface components carried along are those found afresh, and
    /// their volumes as kept up to date are those summed afresh.
    pub(super) fn check(&self) -> Result<(), String> {
        let (fresh, _) =
            label_surface_components(&self.pos, &self.kind, &self.tris, &self.patch, &self.labels);
        let mut to_fresh: HashMap<u32, u32> = HashMap::new();
        let mut to_carried: HashMap<u32, u32> = HashMap::new();
        for (t, (carried, found)) in self.component.iter().zip(&fresh).enumerate() {
            for (&c, &f) in carried.iter().zip(found) {
                let same = (c == NONE_COMPONENT) == (f == NONE_COMPONENT)
                    && (c == NONE_COMPONENT
                        || *to_fresh.entry(c).or_insert(f) == f
                            && *to_carried.entry(f).or_insert(c) == c);
                if !same {
                    return Err(format!(
                        "triangle {t}: carried label surface component {c}, found afresh {f}"
                    ));
                }
            }
        }
        let summed = component_volumes(&self.pos, &self.tris, &self.component, &self.origin);
        for (c, (&kept, &found)) in self.volume.iter().zip(&summed).enumerate() {
            if !((kept - found).abs() <= 1e-6 * found.abs().max(1.0)) {
                return Err(format!(
                    "component {c}: volume kept up to date {kept}, summed afresh {found}"
                ));
            }
        }
        let mut used = vec![false; self.pos.len()];
        for t in &self.tris {
            for &v in t {
                used[v as usize] = true;
            }
        }
        if let Some(v) = used.iter().position(|&u| !u) {
            return Err(format!("vertex {v} ({:?}) unused", self.kind[v]));
        }
        let mut seen: HashMap<(u32, u32, u32), usize> = HashMap::new();
        for (t, tri) in self.tris.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                if let Some(o) = seen.insert((self.patch[t], a, b), t) {
                    return Err(format!(
                        "patch {}: edge {a}-{b} in triangles {o} {:?} and {t} {:?}",
                        self.patch[t], self.tris[o], tri
                    ));
                }
            }
        }
        Ok(())
    }

    fn remesh_block(
        &self,
        blocks: &Blocks,
        s: usize,
        buckets: &[Vec<u32>],
        uses: &[u32],
        closed: &ClosedComponents,
        shared: &Shared,
    ) -> Outcome {
        let own = &buckets[s];
        let empty = Outcome {
            stats: [0; 10],
            moved: Vec::new(),
            dead: Vec::new(),
            made: Vec::new(),
            triangles: Vec::new(),
            runs: Vec::new(),
            volume_changes: Vec::new(),
        };
        if own.is_empty() {
            return empty;
        }
        let (lo, hi) = blocks.trusted(s);

        // local vertices: those of the slab's triangles first
        let mut local = take_local_ids(self.pos.len());
        let mut global: Vec<u32> = Vec::with_capacity(own.len());
        let mut count: Vec<u32> = Vec::with_capacity(own.len());
        let mut local_of = |v: u32, global: &mut Vec<u32>, count: &mut Vec<u32>| -> u32 {
            let l = &mut local[v as usize];
            if *l == NO_LOCAL {
                *l = global.len() as u32;
                global.push(v);
                count.push(0);
            }
            *l
        };
        let mut own_tris = Vec::with_capacity(own.len());
        for &t in own {
            let lt = self.tris[t as usize].map(|v| {
                let l = local_of(v, &mut global, &mut count);
                count[l as usize] += 1;
                l
            });
            own_tris.push(lt);
        }
        let n_own_vertices = global.len();
        let free: Vec<bool> = (0..n_own_vertices)
            .map(|l| count[l] == uses[global[l] as usize])
            .collect();
        // obstacles: the neighbouring slabs' triangles that reach the trusted box
        let mut obstacles = Vec::new();
        for nb in blocks.neighbours(s) {
            for &t in &buckets[nb] {
                let tri = self.tris[t as usize];
                let [a, b, c] = tri.map(|v| self.pos[v as usize]);
                let (tlo, thi) = (a.min(b).min(c), a.max(b).max(c));
                if thi.cmpge(lo).all() && tlo.cmple(hi).all() {
                    obstacles.push(tri.map(|v| local_of(v, &mut global, &mut count)));
                }
            }
        }
        let pos: Vec<DVec3> = global.iter().map(|&g| self.pos[g as usize]).collect();
        let kind: Vec<VertexKind> = (0..global.len())
            .map(|l| {
                if l < n_own_vertices && free[l] {
                    self.kind[global[l] as usize]
                } else {
                    VertexKind::Corner
                }
            })
            .collect();
        let is_free = |v: u32| {
            let l = local[v as usize];
            l != NO_LOCAL && (l as usize) < n_own_vertices && free[l as usize]
        };

        // patches, by global id
        let mut patch_ids: Vec<u32> = own.iter().map(|&t| self.patch[t as usize]).collect();
        patch_ids.sort_unstable();
        patch_ids.dedup();
        let mut patches: Vec<RegionPatch> = patch_ids
            .iter()
            .map(|&p| RegionPatch {
                reference: &shared.references[p as usize],
                triangles: Vec::new(),
                hints: Vec::new(),
                kept: Vec::new(),
                components: Vec::new(),
                offset: shared.patch_offsets.get(p as usize).copied().unwrap_or(0.0),
            })
            .collect();
        let mut local_component = take_table(&LOCAL_COMPONENTS, self.origin.len());
        // per local component: its global one
        let mut components: Vec<u32> = Vec::new();
        let mut volumes = Vec::new();
        for (i, &t) in own.iter().enumerate() {
            let p = patch_ids
                .binary_search(&self.patch[t as usize])
                .expect("patch listed");
            let c = self.component[t as usize].map(|c| {
                if c == NONE_COMPONENT {
                    return NONE_COMPONENT;
                }
                let l = &mut local_component[c as usize];
                if *l == NO_LOCAL {
                    *l = volumes.len() as u32;
                    volumes.push(closed.share[c as usize]);
                    components.push(c);
                }
                *l
            });
            let rp = &mut patches[p];
            rp.triangles.push(own_tris[i]);
            rp.hints.push(self.hint[t as usize]);
            rp.kept.push(self.kept[t as usize]);
            rp.components.push(c);
        }
        return_table(&LOCAL_COMPONENTS, local_component, &components);

        // curve runs: maximal chains of edges with a free end
        let mut curves_here: Vec<u32> = (0..n_own_vertices)
            .filter(|&l| free[l])
            .filter_map(|l| match self.kind[global[l] as usize] {
                VertexKind::Curve(c) => Some(c),
                _ => None,
            })
            .collect();
        curves_here.sort_unstable();
        curves_here.dedup();
        let mut runs = Vec::new();
        let mut run_keys = Vec::new();
        for &c in &curves_here {
            let cv = &self.curves[c as usize];
            let closed = self.closed[c as usize];
            let n = cv.len();
            let edges = if closed { n } else { n - 1 };
            let owned = |i: usize| is_free(cv[i]) || is_free(cv[(i + 1) % n]);
            let to_local = |v: u32| {
                let l = local[v as usize];
                assert_ne!(l, NO_LOCAL, "a vertex of the slab's triangles");
                l
            };
            if closed && (0..edges).all(owned) {
                runs.push(CurveRun {
                    vertices: cv.iter().map(|&v| to_local(v)).collect(),
                    closed: true,
                    reference: &shared.curve_references[c as usize],
                    curve: c,
                });
                run_keys.push((c, 0, edges, true));
                continue;
            }
            // start after an edge that is not owned (an open curve: at its start)
            let first = if closed {
                ((0..edges).find(|&i| !owned(i)).expect("an edge not owned") + 1) % n
            } else {
                0
            };
            let mut k = 0;
            while k < edges {
                let i = (first + k) % n;
                if !owned(i) {
                    k += 1;
                    continue;
                }
                let mut len = 0;
                while k + len < edges && owned((first + k + len) % n) {
                    len += 1;
                }
                runs.push(CurveRun {
                    vertices: (0..=len).map(|j| to_local(cv[(i + j) % n])).collect(),
                    closed: false,
                    reference: &shared.curve_references[c as usize],
                    curve: c,
                });
                run_keys.push((c, i, len, false));
                k += len;
            }
        }

        return_local_ids(local, &global);

        // the guard's cells: about the mean edge length of the slab
        let mean_edge = own_tris
            .iter()
            .map(|t| (pos[t[0] as usize] - pos[t[1] as usize]).length())
            .sum::<f64>()
            / own_tris.len() as f64;
        let cell = (1.5 * mean_edge).max(0.5 * shared.sizing.min());
        let n_region = pos.len();
        let region = Region {
            pos,
            kind,
            patches,
            curves: runs,
            obstacles,
            trusted: (lo, hi),
            volumes,
        };
        let t_slab = std::time::Instant::now();
        let mut r = Remesher::new(region, shared.sizing, shared.eps, cell);
        r.offset_chords = shared.offset_chords;
        r.iterate();
        let result: RegionResult = r.finish();
        if std::env::var_os("SEPTA_DEBUG_WORK").is_some() {
            let mut seen: HashMap<(u32, u32, u32), usize> = HashMap::new();
            for (i, t) in result.triangles.iter().enumerate() {
                for k in 0..3 {
                    let (a, b) = (t.vertices[k], t.vertices[(k + 1) % 3]);
                    if let Some(o) = seen.insert((t.patch, a, b), i) {
                        let info = |v: u32| {
                            let v = v as usize;
                            if v < n_region {
                                format!(
                                    "{v}: region vertex, global {}, own {}, free {}, kind {:?}",
                                    global[v],
                                    v < n_own_vertices,
                                    v < n_own_vertices && free[v],
                                    self.kind[global[v] as usize]
                                )
                            } else {
                                format!("{v}: made here")
                            }
                        };
                        panic!(
                            "slab {s}: edge {a}-{b} twice: {:?} and {:?}\n  {}\n  {}",
                            result.triangles[o].vertices,
                            t.vertices,
                            info(a),
                            info(b)
                        );
                    }
                }
            }
        }

        // back to global ids
        let to_global = |l: u32| -> u32 {
            if (l as usize) < n_region {
                global[l as usize]
            } else {
                NEW + (l - n_region as u32)
            }
        };
        let mut out = empty;
        out.stats = result.stats;
        out.stats[9] = t_slab.elapsed().as_nanos() as u64;
        out.volume_changes = components
            .iter()
            .zip(&result.volumes)
            .map(|(&c, &left)| (c, left - closed.share[c as usize]))
            .filter(|&(_, change)| change != 0.0)
            .collect();
        for l in 0..n_own_vertices {
            if !free[l] {
                continue;
            }
            if result.alive[l] {
                out.moved.push((global[l], result.pos[l]));
            } else {
                out.dead.push(global[l]);
            }
        }
        for l in n_region..result.pos.len() {
            out.made
                .push((result.pos[l], result.kind[l], result.alive[l]));
        }
        let block_of = |vertices: [u32; 3]| {
            // (every region vertex where the remesher left it)
            blocks.of(centroid(&result.pos, &vertices)) as u32
        };
        for t in &result.triangles {
            out.triangles.push(OutcomeTriangle {
                vertices: t.vertices.map(to_global),
                patch: patch_ids[t.patch as usize],
                hint: t.hint,
                kept: t.kept,
                component: t.component.map(|c| {
                    components
                        .get(c as usize)
                        .copied()
                        .unwrap_or(NONE_COMPONENT)
                }),
                block: block_of(t.vertices),
            });
        }
        for ((c, start, edges, whole), cv) in run_keys.into_iter().zip(result.curves) {
            let vertices = cv.into_iter().map(to_global).collect();
            out.runs.push((
                c,
                RunResult {
                    start,
                    edges,
                    whole,
                    vertices,
                },
            ));
        }
        out
    }

    /// Replaces the triangles of the slabs `done` with their outcomes.
    fn merge(&mut self, done: &[usize], outcomes: Vec<Outcome>) {
        let mut processed = vec![
            false;
            self.block
                .iter()
                .map(|&s| s as usize + 1)
                .max()
                .unwrap_or(0)
        ];
        for &s in done {
            if s < processed.len() {
                processed[s] = true;
            }
        }
        // the triangles of the other blocks stay, in order, in place (fresh
        // arrays cost a page fault every few triangles), then come the
        // outcomes'
        let mut n = 0;
        for t in 0..self.tris.len() {
            if !processed[self.block[t] as usize] {
                self.tris[n] = self.tris[t];
                self.patch[n] = self.patch[t];
                self.hint[n] = self.hint[t];
                self.kept[n] = self.kept[t];
                self.component[n] = self.component[t];
                self.block[n] = self.block[t];
                n += 1;
            }
        }
        self.tris.truncate(n);
        self.patch.truncate(n);
        self.hint.truncate(n);
        self.kept.truncate(n);
        self.component.truncate(n);
        self.block.truncate(n);
        let mut alive = vec![true; self.pos.len()];
        let mut runs_by_curve: HashMap<u32, Vec<RunResult>> = HashMap::new();
        for o in outcomes {
            let base = self.pos.len() as u32;
            for (v, p) in o.moved {
                self.pos[v as usize] = p;
            }
            for v in o.dead {
                alive[v as usize] = false;
            }
            for (p, k, a) in o.made {
                self.pos.push(p);
                self.kind.push(k);
                alive.push(a);
            }
            let g = |v: u32| if v >= NEW { base + (v - NEW) } else { v };
            for t in o.triangles {
                self.tris.push(t.vertices.map(g));
                self.patch.push(t.patch);
                self.hint.push(t.hint);
                self.kept.push(t.kept);
                self.component.push(t.component);
                self.block.push(t.block);
            }
            for (c, mut run) in o.runs {
                run.vertices = run.vertices.into_iter().map(g).collect();
                runs_by_curve.entry(c).or_default().push(run);
            }
            // (in block order: the same sums for any number of threads)
            for (c, change) in o.volume_changes {
                self.volume[c as usize] += change;
            }
        }
        let mut curves: Vec<u32> = runs_by_curve.keys().copied().collect();
        curves.sort_unstable();
        for c in curves {
            let runs = runs_by_curve.remove(&c).expect("listed");
            let cv = std::mem::take(&mut self.curves[c as usize]);
            self.curves[c as usize] = splice(&cv, self.closed[c as usize], runs);
        }
        self.compact(alive);
    }

    /// Removes dead vertices (renumbering the rest in order).
    fn compact(&mut self, alive: Vec<bool>) {
        if alive.iter().all(|&a| a) {
            return;
        }
        let mut map = vec![u32::MAX; self.pos.len()];
        let mut next = 0;
        for v in 0..self.pos.len() {
            if alive[v] {
                map[v] = next as u32;
                self.pos[next] = self.pos[v];
                self.kind[next] = self.kind[v];
                next += 1;
            }
        }
        self.pos.truncate(next);
        self.kind.truncate(next);
        self.tris
            .par_iter_mut()
            .with_min_len(1 << 14)
            .for_each(|t| *t = t.map(|v| map[v as usize]));
        for cv in &mut self.curves {
            for v in cv.iter_mut() {
                *v = map[*v as usize];
            }
            debug_assert!(cv.iter().all(|&v| v != u32::MAX), "a curve vertex died");
        }
    }
}

/// The centroid of triangle `t` over positions `pos`.
#[inline]
fn centroid(pos: &[DVec3], t: &[u32; 3]) -> DVec3 {
    (pos[t[0] as usize] + pos[t[1] as usize] + pos[t[2] as usize]) / 3.0
}

/// The signed volume each component encloses, over triangles `tris` (of
/// components `component`) and vertices `pos`, summed in triangle order
/// about each component's `origin`. The second side of a triangle is the
/// first turned over: its volume counts negative.
fn component_volumes(
    pos: &[DVec3],
    tris: &[[u32; 3]],
    component: &[Sides],
    origin: &[DVec3],
) -> Vec<f64> {
    let cone = |t: &[u32; 3], c: u32| {
        if c == NONE_COMPONENT {
            return 0.0;
        }
        let o = origin[c as usize];
        let [a, b, c] = t.map(|v| pos[v as usize] - o);
        a.dot(b.cross(c)) / 6.0
    };
    let part: Vec<[f64; 2]> = tris
        .par_iter()
        .zip(component)
        .map(|(t, &[c0, c1])| [cone(t, c0), -cone(t, c1)])
        .collect();
    // summed in triangle order: the same for any number of threads
    let mut volume = vec![0.0; origin.len()];
    for (sides, v) in component.iter().zip(part) {
        for k in 0..2 {
            if sides[k] != NONE_COMPONENT {
                volume[sides[k] as usize] += v[k];
            }
        }
    }
    volume
}

/// The connected components of every label's surface, over triangles
/// `tris` (of patches `patch`, whose label ids are `labels`) and vertices
/// `pos` (of kinds `kind`): per triangle the components of its two sides
/// (see [`Sides`]), per component a point of it.
///
/// A label's surface is a closed manifold: at every edge exactly two of its
/// triangles meet. Within a patch, the triangles around a vertex that is on
/// no junction curve are one piece of both its labels' surfaces; at an edge
/// between two junction vertices, the sides of the same label are joined
/// across patches. Every component is a closed surface, so its signed
/// enclosed volume is defined; keeping it from passing through zero keeps
/// a small label region from turning inside out, which no crossing test sees
/// (a region can jump through itself between two states without a crossing
/// in either).
fn label_surface_components(
    pos: &[DVec3],
    kind: &[VertexKind],
    tris: &[[u32; 3]],
    patch: &[u32],
    labels: &[[u32; 2]],
) -> (Vec<Sides>, Vec<DVec3>) {
    let junction = |v: u32| matches!(kind[v as usize], VertexKind::Curve(_) | VertexKind::Corner);
    // side 2t is triangle t's first label's, 2t + 1 its second's
    let mut dsu = Dsu::new(2 * tris.len());
    // the first triangle seen at each vertex off the junction curves
    let mut first = vec![u32::MAX; pos.len()];
    // edges between junction vertices: (lower, higher, triangle)
    let mut junction_edges: Vec<(u32, u32, u32)> = Vec::new();
    for (t, tri) in tris.iter().enumerate() {
        let t = t as u32;
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            if !junction(a) {
                let f = &mut first[a as usize];
                if *f == u32::MAX {
                    *f = t;
                } else {
                    dsu.union(2 * *f, 2 * t);
                    dsu.union(2 * *f + 1, 2 * t + 1);
                }
            } else if junction(b) {
                junction_edges.push((a.min(b), a.max(b), t));
            }
        }
    }
    junction_edges.sort_unstable();
    let mut sides: Vec<(u32, u32)> = Vec::new();
    for run in junction_edges.chunk_by(|x, y| (x.0, x.1) == (y.0, y.1)) {
        sides.clear();
        for &(_, _, t) in run {
            let [a, b] = labels[patch[t as usize] as usize];
            sides.push((a, 2 * t));
            sides.push((b, 2 * t + 1));
        }
        sides.sort_unstable();
        // (two per label on a valid mesh; all of them joined otherwise)
        for same in sides.chunk_by(|x, y| x.0 == y.0) {
            for w in same.windows(2) {
                dsu.union(w[0].1, w[1].1);
            }
        }
    }
    let mut index = vec![NONE_COMPONENT; 2 * tris.len()];
    let mut origin = Vec::new();
    let of_triangle = tris
        .iter()
        .enumerate()
        .map(|(t, tri)| {
            [0, 1].map(|k| {
                let r = dsu.find(2 * t as u32 + k) as usize;
                if index[r] == NONE_COMPONENT {
                    index[r] = origin.len() as u32;
                    origin.push(pos[tri[0] as usize]);
                }
                index[r]
            })
        })
        .collect();
    (of_triangle, origin)
}

/// Curve `cv` with its remeshed runs put in place.
fn splice(cv: &[u32], closed: bool, runs: Vec<RunResult>) -> Vec<u32> {
    let n = cv.len();
    let mut from: HashMap<usize, (usize, Vec<u32>)> = HashMap::with_capacity(runs.len());
    let mut inside = vec![false; n];
    for RunResult {
        start,
        edges,
        whole,
        vertices,
    } in runs
    {
        if whole {
            return vertices;
        }
        for j in 1..edges {
            inside[(start + j) % n] = true;
        }
        from.insert(start, (edges, vertices));
    }
    let mut out = Vec::with_capacity(n);
    // closed: walk once around from a vertex inside no run; open: from the start
    let first = if closed {
        (0..n).find(|&i| !inside[i]).unwrap_or(0)
    } else {
        0
    };
    let (mut i, mut steps) = (first, 0);
    while steps < n {
        match from.remove(&i) {
            Some((edges, vertices)) => {
                // all but its last vertex: the next step's
                out.extend_from_slice(&vertices[..vertices.len() - 1]);
                steps += edges;
                i = (i + edges) % n;
                if !closed && steps >= n - 1 {
                    out.push(cv[n - 1]);
                    break;
                }
            }
            None => {
                out.push(cv[i]);
                steps += 1;
                i = (i + 1) % n;
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::{
        Blocks, COLOURS, NEW, Outcome, OutcomeTriangle, RunResult, Work, by_size_largest_first,
        label_surface_components, largest_first, splice,
    };
    use crate::remesh::network::VertexKind;
    use glam::DVec3;

    /// A pass of one colour takes, from each block of a later colour, only
    /// the points within the halo of a block of that colour, and the boxes
    /// in which two blocks of one colour may make triangles never meet.
    #[test]
    fn halos_take_strips_of_later_blocks_only() {
        let blocks = Blocks {
            axes: [0, 2],
            origin: [-3.0, 0.0],
            width: [10.0, 10.0],
            count: [4, 5],
            reach: 2.0,
            halo: 1.5,
        };
        let grown = |b: usize, by: f64| {
            let (lo, hi) = blocks.trusted(b);
            let r = blocks.halo + blocks.reach - by;
            (lo + DVec3::new(r, 0.0, r), hi - DVec3::new(r, 0.0, r))
        };
        let inside = |p: DVec3, (lo, hi): (DVec3, DVec3)| p.cmpge(lo).all() && p.cmple(hi).all();
        let mut taken = 0;
        for x in 0..80 {
            for z in 0..100 {
                let p = DVec3::new(-3.0 + 0.5 * x as f64 + 0.25, 7.0, 0.5 * z as f64 + 0.25);
                let own = blocks.of(p);
                for colour in 0..COLOURS {
                    let b = blocks.pass_block(p, own, colour);
                    if b == own {
                        // not taken: its own colour comes first, or it lies
                        // beyond every halo of this colour
                        let near = (0..blocks.len()).any(|c| {
                            blocks.colour(c) == colour
                                && c != own
                                && inside(p, grown(c, blocks.halo))
                        });
                        assert!(
                            blocks.colour(own) <= colour || !near,
                            "{p} of {own} left by {colour}"
                        );
                    } else {
                        taken += 1;
                        assert_eq!(blocks.colour(b), colour);
                        assert!(blocks.colour(own) > colour);
                        assert!(inside(p, grown(b, blocks.halo)), "{p} taken by {b}");
                    }
                }
            }
        }
        assert!(taken > 0);
        for a in 0..blocks.len() {
            for b in 0..a {
                if blocks.colour(a) == blocks.colour(b) {
                    let ((alo, ahi), (blo, bhi)) = (blocks.trusted(a), blocks.trusted(b));
                    let apart = (0..3).any(|k| ahi[k] < blo[k] || bhi[k] < alo[k]);
                    assert!(apart, "blocks {a} and {b} of colour {}", blocks.colour(a));
                }
            }
        }
    }

    /// Two unit cubes, of labels 1 and 2, side by side in label 0 (patches
    /// 0|1, 0|2 and 1|2, the four vertices of the shared square on the
    /// junction curve): one component per label's surface, joined across
    /// the patches at the curve, enclosing the label's volume (label 0's
    /// surface faces into the cubes: -2).
    #[test]
    fn label_surfaces_are_joined_across_patches() {
        let id = |x: usize, y: usize, z: usize| (x * 4 + y * 2 + z) as u32;
        let pos: Vec<DVec3> = (0..12)
            .map(|i| DVec3::new((i / 4) as f64, ((i / 2) % 2) as f64, (i % 2) as f64))
            .collect();
        let kind: Vec<VertexKind> = (0..12)
            .map(|i| {
                if i / 4 == 1 {
                    VertexKind::Corner
                } else {
                    VertexKind::Interior
                }
            })
            .collect();
        let labels = vec![[0, 1], [0, 2], [1, 2]];
        let (mut tris, mut patch) = (Vec::new(), Vec::new());
        for x0 in 0..2 {
            for axis in 0..3 {
                for side in 0..2 {
                    // the square of cube x0 at `side` along `axis`, corners in a cycle
                    let corner = |a: usize, b: usize| {
                        let mut c = [x0, 0, 0];
                        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
                        c[axis] = if axis == 0 { x0 + side } else { side };
                        c[u] = if u == 0 { x0 + a } else { a };
                        c[v] = if v == 0 { x0 + b } else { b };
                        id(c[0], c[1], c[2])
                    };
                    let q = [corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)];
                    let mut out = DVec3::ZERO;
                    out[axis] = if side == 1 { 1.0 } else { -1.0 };
                    let shared = axis == 0 && x0 + side == 1;
                    if shared && x0 == 1 {
                        continue;
                    }
                    // normals from the first label into the second
                    let (p, normal) = if shared {
                        (2, DVec3::X)
                    } else {
                        (x0 as u32, -out)
                    };
                    let p3 = |v: u32| pos[v as usize];
                    let n = (p3(q[1]) - p3(q[0])).cross(p3(q[2]) - p3(q[0]));
                    let q = if n.dot(normal) > 0.0 {
                        q
                    } else {
                        [q[0], q[3], q[2], q[1]]
                    };
                    tris.push([q[0], q[1], q[2]]);
                    tris.push([q[0], q[2], q[3]]);
                    patch.extend([p, p]);
                }
            }
        }
        assert_eq!(tris.len(), 22);
        let (sides, origin) = label_surface_components(&pos, &kind, &tris, &patch, &labels);
        assert_eq!(origin.len(), 3, "one component per label");
        let mut volume = [0.0; 3];
        let mut label_of = [u32::MAX; 3];
        for ((t, s), &p) in tris.iter().zip(&sides).zip(&patch) {
            let [a, b, c] = t.map(|v| pos[v as usize]);
            let cone = a.dot(b.cross(c)) / 6.0;
            for k in 0..2 {
                let l = labels[p as usize][k];
                let c = s[k] as usize;
                assert!(
                    label_of[c] == u32::MAX || label_of[c] == l,
                    "one label per component"
                );
                label_of[c] = l;
                volume[c] += if k == 0 { cone } else { -cone };
            }
        }
        for (c, &l) in label_of.iter().enumerate() {
            let want = if l == 0 { -2.0 } else { 1.0 };
            assert!((volume[c] - want).abs() < 1e-12, "label {l}: {}", volume[c]);
        }
    }

    /// Every item is worked once and its result comes back in the order of
    /// the list, whatever the number of threads.
    #[test]
    fn largest_first_keeps_the_order_of_the_list() {
        let todo: Vec<usize> = (0..37).map(|i| (i * 7919) % 101).collect();
        let expect: Vec<usize> = todo.iter().map(|b| b * b).collect();
        for threads in [1, 2, 3, 8] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("a pool");
            let runs = std::sync::atomic::AtomicUsize::new(0);
            let got = pool.install(|| {
                largest_first(&todo, |b| {
                    runs.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                    b * b
                })
            });
            assert_eq!(got, expect, "{threads} threads");
            assert_eq!(runs.into_inner(), todo.len());
        }
        assert!(largest_first(&[], |b: usize| b).is_empty());
        // by size: results in item order whatever the sizes
        let sizes = [3usize, 40, 1, 40, 7];
        let got = by_size_largest_first(sizes.len(), |i| sizes[i], |i| 10 * i);
        assert_eq!(got, vec![0, 10, 20, 30, 40]);
    }

    /// A block's outcome that made two vertices, the second of them taken
    /// away again in the same pass (a curve vertex split, then collapsed):
    /// the merged mesh must not keep it as an unused vertex.
    #[test]
    fn a_vertex_made_and_removed_in_one_pass_is_not_kept() {
        let p = |x: f64, y: f64| DVec3::new(x, y, 0.0);
        let mut work = Work::new(
            vec![p(0.0, 0.0), p(1.0, 0.0), p(0.0, 1.0)],
            vec![VertexKind::Interior; 3],
            vec![[0, 1, 2]],
            vec![0],
            vec![[0, 1]],
            vec![0],
            Vec::new(),
            Vec::new(),
        );
        let outcome = Outcome {
            stats: [0; 10],
            moved: Vec::new(),
            dead: Vec::new(),
            made: vec![
                (p(0.5, 0.0), VertexKind::Interior, true),
                (p(0.25, 0.0), VertexKind::Interior, false),
            ],
            // the triangle split at the first made vertex
            triangles: [[0, NEW, 2], [NEW, 1, 2]]
                .map(|vertices| OutcomeTriangle {
                    vertices,
                    patch: 0,
                    hint: 0,
                    kept: false,
                    // (the component of the triangle they replace)
                    component: [0, 1],
                    block: 0,
                })
                .into(),
            runs: Vec::new(),
            volume_changes: Vec::new(),
        };
        work.merge(&[0], vec![outcome]);
        assert_eq!(work.pos.len(), 4);
        assert_eq!(work.tris.len(), 2);
        assert!(work.check().is_ok(), "{:?}", work.check());
    }

    fn run(start: usize, edges: usize, whole: bool, vertices: Vec<u32>) -> RunResult {
        RunResult {
            start,
            edges,
            whole,
            vertices,
        }
    }

    #[test]
    fn runs_replace_their_inner_vertices() {
        // open: 0-1-2-3-4-5, runs over 1..=3 (new 1, 10, 11, 12, 3) and 4..=5
        let cv = [0, 1, 2, 3, 4, 5];
        let out = splice(
            &cv,
            false,
            vec![
                run(1, 2, false, vec![1, 10, 11, 12, 3]),
                run(4, 1, false, vec![4, 13, 5]),
            ],
        );
        assert_eq!(out, vec![0, 1, 10, 11, 12, 3, 4, 13, 5]);
        // a run to the end of an open curve, one that collapsed its inner vertex
        assert_eq!(
            splice(&cv, false, vec![run(3, 2, false, vec![3, 5])]),
            vec![0, 1, 2, 3, 5]
        );
        assert_eq!(
            splice(&cv, false, vec![run(0, 5, false, vec![0, 9, 5])]),
            vec![0, 9, 5]
        );
        // closed: a run over the wrap (4, 5, 0, 1)
        let out = splice(&cv, true, vec![run(4, 3, false, vec![4, 20, 1])]);
        assert_eq!(out, vec![1, 2, 3, 4, 20]);
        // the whole closed curve
        assert_eq!(
            splice(&cv, true, vec![run(0, 6, true, vec![7, 8, 9])]),
            vec![7, 8, 9]
        );
        // no run: unchanged
        assert_eq!(splice(&cv, true, vec![]), cv.to_vec());
    }
}
