//! Obstacle-set policy at capacity (issue 17): which of the offered obstacle points the
//! controller keeps for the safety filter when more arrive than its set holds, and what
//! it reports about the rest.
//!
//! The filter enforces the barriers with the smallest `h` (`MAX_ACTIVE_BARRIERS` of
//! them, `cbf.rs`), so the set must hold the points whose barriers are smallest, not the
//! points nearest to the vehicle: a wall approached head-on has a smaller barrier than a
//! nearer point beside the path (`h = |d|² + μ dᵀḋ`, the velocity term is negative when
//! closing). Nearest-first kept 632 tiny spheres beside the path and dropped the wall
//! ahead until it was 0.34 m away (`scenes/points_then_wall.toml`).
//!
//! **Policy** ([`Ranking::Critical`], the multi-barrier variants). Each point gets the
//! key `k = min(h, |d|²)` (m²): its barrier value with the variant's velocity (relative
//! velocity for the relative variants), but never more than its squared distance, so a
//! near point that is moving away still ranks by its distance. Points are ordered by
//! `(tier, k)`: tier 0 is the most critical point of its obstacle id (an extended
//! obstacle reported as several points keeps at least its most critical one before any
//! obstacle gets a second), tier 1 every other point of an id. The set keeps the
//! `N` smallest in that order; ties keep the point offered first. Hence:
//!
//! * no dropped point is more critical than a kept point of the same tier: a far point
//!   (larger key) is never kept over a nearer or closing one;
//! * with at most `N` distinct ids, every obstacle keeps at least one point;
//! * with at most `N` points offered, all are kept, in the order offered (so nothing
//!   changes below capacity).
//!
//! [`Ranking::Nearest`] (the closest-obstacle variants, `paper` and `relative`, whose law
//! acts on the closest point only) is the published policy: key `|d|²`, one tier; the
//! result equals [`ObstacleSet::insert_nearest`] point by point.
//!
//! **Exactness.** Streaming, one point at a time: when a point of id X arrives and the set
//! holds X's tier-0 point with a larger key, that point is demoted to tier 1 and the new
//! one is tier 0; otherwise the new point is tier 1 if the set holds a point of X, else
//! tier 0. The set then keeps the `N` smallest `(tier, k)` of everything offered so far:
//! only a stored point's order ever worsens (a demotion), and the demoted point stays in
//! the candidates, so the `N` best of the set plus the new point are the `N` best of the
//! prefix. (A point of X whose better sibling was dropped earlier is ranked tier 0 but
//! cannot enter: the set was then full of tier-0 points with smaller keys.)
//!
//! **Bound.** No allocation. Below capacity a point costs its key and a push (the usual
//! case: nothing is ranked). When the set first overflows, the tiers of the stored points
//! are assigned once (what the streaming demotions would have given: each id's first
//! smallest key is tier 0; O(N·D) for D distinct ids, at most O(N²)); after that each
//! offered point costs one O(1) comparison with the cached worst stored entry, and when it
//! may enter one O(N) scan for its id (skipped for a run of one id) and, per changed rank
//! (a demotion, the store), a rescan of that rank's block of 8 slots and of the `N/8`
//! blocks' worst entries (the cached worst is not recomputed while no stored rank
//! changed): O(N) per point, O(N² + M·N) for M points (M bounded by the caller's batch).
//! The blocks and the O(N·D) tiers (2026-12-05) give the same slots as the full rescans
//! (`cached_searches_give_the_streaming_selection_slot_for_slot`, N = 8, 20, 32). Non-finite or implausible (beyond ±`INPUT_LIMIT`) points are rejected before ranking.
//!
//! [`Selector`] applies the policy one point at a time (a sensor batch as it arrives, e.g.
//! the firmware's obstacle link); [`select`] applies it to a slice.
//!
//! **Report** ([`SetReport`]): points offered, kept, dropped at capacity, and of the
//! dropped ones how many had `h ≤ δ1` ("near": a barrier the filter would have
//! considered this step), with the smallest dropped key. A dropped near point means the
//! set was too small for the situation; the telemetry carries it to the run summary.
//!
//! May import: `crate::obstacle` (points and the set), `crate::cbf` (the input limit), `crate::Vec3`.

use crate::cbf::INPUT_LIMIT;
use crate::obstacle::{ObstaclePoint, ObstacleSet, DEFAULT_OBSTACLE_CAPACITY};
use crate::Vec3;

/// How points are ranked when the set is full.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Ranking {
    /// Nearest first (key `|d|²`), one tier: the published policy.
    Nearest,
    /// Most critical first (key `min(h, |d|²)`), at least one point per obstacle id.
    Critical {
        /// μ, s: the barrier's velocity weight.
        mu: f32,
        /// Use the relative velocity `ṗ − v̄` (relative variants) rather than `ṗ`.
        relative: bool,
    },
}

/// What one selection did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SetReport {
    /// Points offered (finite ones).
    pub offered: u16,
    /// Points kept in the set.
    pub kept: u16,
    /// Points dropped because the set was full.
    pub dropped: u16,
    /// Dropped points whose barrier had `h ≤ δ1` (the filter would have considered them).
    pub dropped_near: u16,
    /// Points (or velocities) non-finite or beyond ±[`INPUT_LIMIT`], or every point when the
    /// vehicle state is: rejected, not ranked (the caller counts them as bad input).
    pub rejected: u16,
    /// Smallest key `min(h, |d|²)` (m², `Nearest`: `|d|²`) among the dropped points; `+∞` if none.
    pub min_dropped_key: f32,
}

/// Per-slot ranking state: (tier, key) as one integer in keep order, the tier above the
/// key's bits mapped to an increasing integer ([`key_bits`]): for finite keys `a.0 > b.0`
/// exactly when `a` is later in the keep order (higher tier, or the same tier and a larger
/// key), so the worst entry is found by integer comparisons.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Rank(u64);

impl Rank {
    #[inline]
    fn new(tier: u8, key: f32) -> Self {
        Rank::from_bits(tier, key_bits(key))
    }

    #[inline]
    fn from_bits(tier: u8, kb: u32) -> Self {
        Rank((u64::from(tier) << 32) | u64::from(kb))
    }

    #[inline]
    fn tier(self) -> u8 {
        (self.0 >> 32) as u8
    }

    /// [`key_bits`] of the key: compares as the finite keys do.
    #[inline]
    fn key_bits(self) -> u32 {
        self.0 as u32
    }

    #[inline]
    fn with_tier(self, tier: u8) -> Self {
        Rank::from_bits(tier, self.key_bits())
    }

    /// Strictly worse (later in the keep order).
    #[inline]
    fn worse_than(&self, o: &Rank) -> bool {
        self.0 > o.0
    }
}

/// A finite key's bits mapped to an increasing integer: `key_bits(a) < key_bits(b)` exactly
/// when `a < b`, equal exactly when `a == b` (`-0.0` counts as `0.0`).
#[inline]
fn key_bits(key: f32) -> u32 {
    let bits = (key + 0.0).to_bits();
    if bits & 0x8000_0000 != 0 {
        !bits
    } else {
        bits | 0x8000_0000
    }
}

/// Every component within ±[`INPUT_LIMIT`] (false for NaN and ±∞).
#[inline]
fn plausible(v: &Vec3) -> bool {
    v.x.abs() <= INPUT_LIMIT && v.y.abs() <= INPUT_LIMIT && v.z.abs() <= INPUT_LIMIT
}

/// Key of `o` for a vehicle at `p` moving at `v` (NED), and its barrier value `h` (m²).
#[inline]
fn key_of(ranking: Ranking, p: &Vec3, v: &Vec3, o: &ObstaclePoint) -> (f32, f32) {
    key_parts(ranking, p, v, &o.point, o.velocity.as_ref())
}

/// [`key_of`] of the point `point` with velocity `velocity`.
#[inline(always)]
fn key_parts(ranking: Ranking, p: &Vec3, v: &Vec3, point: &Vec3, velocity: Option<&Vec3>) -> (f32, f32) {
    let d = point - p;
    // d here points from the vehicle to the obstacle; the barrier's d is p − p̄ = −d.
    let dist_sq = d.norm_squared();
    match ranking {
        Ranking::Nearest => (dist_sq, dist_sq),
        Ranking::Critical { mu, relative } => {
            // A point without a velocity is fixed: `v − 0` is `v` bit for bit.
            let d_dot = match velocity {
                Some(w) if relative => v - w,
                _ => *v,
            };
            let h = dist_sq - mu * d.dot(&d_dot);
            (if h < dist_sq { h } else { dist_sq }, h)
        }
    }
}

/// What [`Selector::offer`] did with a point.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Offer {
    /// Stored (possibly in place of a less critical point, counted as dropped).
    Kept,
    /// Not stored: the set is full of more critical points.
    Dropped,
    /// Non-finite or beyond ±`INPUT_LIMIT` (or the vehicle state is): not ranked.
    Rejected,
}

/// The ranking state of one selection, kept beside the set it fills (so that [`select`]
/// works in place and [`Selector`] owns both).
#[derive(Clone, Debug)]
struct Ranker<const N: usize> {
    ranks: [Rank; N],
    /// Index of the worst stored entry (valid once the set is full).
    worst: usize,
    /// Per block of [`BLOCK`] slots (the first `⌈N / BLOCK⌉` entries), the index of its
    /// first worst entry (valid once the set is full): a change of one rank rescans its
    /// block and the blocks' worst entries, not all `N`.
    block_worst: [usize; N],
    /// The last sibling search (`Critical`, once tiered): `(id, index of that id's tier-0
    /// entry, if the set holds one)`, updated by every change of the set, so that a run of
    /// points of one id (a memory's static cells) is not rescanned per point. A full set
    /// holds at most one tier-0 entry per id (the tiering gives one, a new tier-0 entry
    /// demotes the old one), so the search's first match is that entry.
    sibling: Option<(u16, Option<usize>)>,
    /// The tiers of the stored entries are valid (computed when the set first fills:
    /// below capacity nothing is dropped and the tiers are not needed).
    tiered: bool,
    report: SetReport,
    /// Count the dropped points in the report (`dropped`, `dropped_near`,
    /// `min_dropped_key`); off for a caller that reads only the set ([`Selector::set_only`]).
    count_drops: bool,
    ranking: Ranking,
    delta1: f32,
    p: Vec3,
    v: Vec3,
    state_ok: bool,
}

impl<const N: usize> Ranker<N> {
    fn new(ranking: Ranking, delta1: f32, p: &Vec3, v: &Vec3) -> Self {
        Ranker {
            ranks: [Rank(0); N],
            worst: 0,
            block_worst: [0; N],
            sibling: None,
            tiered: false,
            report: SetReport { min_dropped_key: f32::INFINITY, ..SetReport::default() },
            count_drops: true,
            ranking,
            delta1,
            p: *p,
            v: *v,
            state_ok: plausible(p) && plausible(v),
        }
    }

    /// The tiers of a full set holding every point offered so far, in offer order: tier 1
    /// for a point whose id has an earlier point with a key ≤ its own or a later one with a
    /// smaller key (what the streaming demotions give). O(N²) once per selection.
    /// A point is tier 0 exactly when it is the first of its id's smallest key: one pass
    /// finds each id's first smallest entry (a table of the distinct ids, `D` of them), a
    /// second sets the tiers; O(N·D), at most O(N²).
    fn assign_tiers(&mut self, set: &ObstacleSet<N>) {
        self.tiered = true;
        if !matches!(self.ranking, Ranking::Critical { .. }) {
            return;
        }
        let pts = set.as_slice();
        // (id, index of its first smallest key) per distinct id, and each point's entry.
        let mut best = [(0u16, 0usize); N];
        let mut entry = [0usize; N];
        let mut d = 0;
        for (i, (q, r)) in pts.iter().zip(self.ranks.iter()).enumerate() {
            let e = match best.get(..d).and_then(|b| b.iter().position(|&(id, _)| id == q.id)) {
                Some(e) => {
                    let cur = best.get(e).map_or(i, |b| b.1);
                    if self.ranks.get(cur).is_some_and(|rc| r.key_bits() < rc.key_bits()) {
                        if let Some(b) = best.get_mut(e) {
                            b.1 = i;
                        }
                    }
                    e
                }
                None => {
                    if let Some(b) = best.get_mut(d) {
                        *b = (q.id, i);
                    }
                    d += 1;
                    d - 1
                }
            };
            if let Some(x) = entry.get_mut(i) {
                *x = e;
            }
        }
        for (i, r) in self.ranks.iter_mut().enumerate().take(pts.len()) {
            let first_best = entry.get(i).and_then(|&e| best.get(e)).is_some_and(|b| b.1 == i);
            *r = r.with_tier(u8::from(!first_best));
        }
    }

    /// Recomputes the worst entry of every block and of the set (`len` entries).
    fn rank_all(&mut self, len: usize) {
        for b in 0..len.div_ceil(BLOCK) {
            self.rank_block(b, len);
        }
        self.rank_blocks(len);
    }

    /// Rank `i` changed: its block's worst entry and the set's.
    fn rank_changed(&mut self, i: usize, len: usize) {
        self.rank_block(i / BLOCK, len);
        self.rank_blocks(len);
    }

    fn rank_block(&mut self, b: usize, len: usize) {
        let lo = b * BLOCK;
        let w = worst_index(self.ranks.get(lo..len.min(lo + BLOCK)).unwrap_or(&[]));
        if let Some(x) = self.block_worst.get_mut(b) {
            *x = lo + w;
        }
    }

    /// The set's first worst entry from the blocks' (the first block of the largest rank:
    /// blocks are in slot order, so this is the first worst slot).
    fn rank_blocks(&mut self, len: usize) {
        let rank = |i: usize| self.ranks.get(i).map_or(0, |r| r.0);
        let blocks = self.block_worst.get(..len.div_ceil(BLOCK)).unwrap_or(&[]);
        let Some(&first) = blocks.first() else {
            self.worst = 0;
            return;
        };
        let (mut w, mut rw) = (first, rank(first));
        for &i in blocks.iter().skip(1) {
            let ri = rank(i);
            if ri > rw {
                (w, rw) = (i, ri);
            }
        }
        self.worst = w;
    }

    fn offer(&mut self, set: &mut ObstacleSet<N>, o: &ObstaclePoint) -> Offer {
        let (key, h) = key_of(self.ranking, &self.p, &self.v, o);
        let point_ok = plausible(&o.point) && o.velocity.is_none_or(|w| plausible(&w));
        self.offer_ranked(set, key, h, point_ok, o.id, || *o)
    }

    /// [`Self::offer`] of the point `make()` (built only when stored) of id `id`, key `key`,
    /// barrier value `h`, plausible when `point_ok`.
    #[inline(always)]
    fn offer_ranked(
        &mut self,
        set: &mut ObstacleSet<N>,
        key: f32,
        h: f32,
        point_ok: bool,
        id: u16,
        make: impl FnOnce() -> ObstaclePoint,
    ) -> Offer {
        if !self.state_ok || !point_ok || !key.is_finite() || !h.is_finite() {
            self.report.rejected = self.report.rejected.saturating_add(1);
            return Offer::Rejected;
        }
        self.report.offered = self.report.offered.saturating_add(1);
        let len = set.len();
        if len < N {
            // Below capacity: stored in offer order, nothing ranked yet.
            if set.points_mut().push(make()).is_err() {
                return Offer::Dropped; // unreachable: len < N
            }
            if let Some(slot) = self.ranks.get_mut(len) {
                // The key's raw bits: ranked (encoded) only when the set overflows.
                *slot = Rank(u64::from(key.to_bits()));
            }
            return Offer::Kept;
        }
        self.offer_full(set, id, key, h, len, make)
    }

    /// [`Self::offer`] past capacity.
    #[inline(always)]
    fn offer_full(
        &mut self,
        set: &mut ObstacleSet<N>,
        id: u16,
        key: f32,
        h: f32,
        len: usize,
        make: impl FnOnce() -> ObstaclePoint,
    ) -> Offer {
        if !self.tiered {
            for r in self.ranks.iter_mut() {
                *r = Rank::new(0, f32::from_bits(r.0 as u32));
            }
            self.assign_tiers(set);
            self.rank_all(len);
        }
        // Fast reject: a full set whose worst entry is tier 0 with a key ≤ this one
        // cannot take it (whatever its id: see the module docs).
        let kb = key_bits(key);
        if self.ranks.get(self.worst).is_some_and(|w| w.tier() == 0 && kb >= w.key_bits()) {
            if self.count_drops {
                drop_point(&mut self.report, key, h, self.delta1);
            }
            return Offer::Dropped;
        }
        let mut r = Rank::from_bits(0, kb);
        let critical = matches!(self.ranking, Ranking::Critical { .. });
        let mut sibling = None;
        if critical {
            sibling = match self.sibling {
                Some((cached, s)) if cached == id => s,
                _ => set
                    .as_slice()
                    .iter()
                    .zip(self.ranks.iter())
                    .position(|(q, rq)| q.id == id && rq.tier() == 0),
            };
            if let Some(s) = sibling {
                match self.ranks.get_mut(s) {
                    Some(rs) if kb < rs.key_bits() => {
                        *rs = rs.with_tier(1);
                        // A demotion is the only change of a stored rank: the cached worst
                        // entry is recomputed then (else it is still `worst_index(ranks)`).
                        self.rank_changed(s, len);
                    }
                    _ => r = r.with_tier(1),
                }
            }
        }
        let ranks = self.ranks.get(..len).unwrap_or(&[]);
        let Some(w) = ranks.get(self.worst).copied() else {
            self.sibling = None;
            return Offer::Dropped;
        };
        if !w.worse_than(&r) {
            // Not stored, nothing changed (a demotion always stores: the worst is then
            // tier 1 and the point tier 0): `sibling` is still this id's tier-0 entry.
            if critical {
                self.sibling = Some((id, sibling));
            }
            if self.count_drops {
                drop_point(&mut self.report, key, h, self.delta1);
            }
            return Offer::Dropped;
        }
        let (Some(slot), Some(rs)) = (set.points_mut().get_mut(self.worst), self.ranks.get_mut(self.worst))
        else {
            self.sibling = None;
            return Offer::Dropped; // unreachable: `worst` < len
        };
        // The evicted point (read only now: most offers are dropped above).
        if self.count_drops {
            let (wkey, wh) = key_of(self.ranking, &self.p, &self.v, slot);
            drop_point(&mut self.report, wkey, wh, self.delta1);
        }
        *slot = make();
        *rs = r;
        if critical {
            // Stored in the worst slot: as tier 0 it is now its id's tier-0 entry; as tier 1
            // its tier-0 sibling stays (the slot replaced was worse than tier 1 with this key,
            // so not that tier-0 sibling).
            self.sibling = Some((id, if r.tier() == 0 { Some(self.worst) } else { sibling }));
        }
        self.rank_changed(self.worst, len);
        Offer::Kept
    }

    fn report(&self, kept: usize) -> SetReport {
        SetReport { kept: kept as u16, ..self.report }
    }
}

/// The policy applied one point at a time (e.g. as a sensor batch arrives): offer the
/// points, then take the set and the report. [`select`] is the same over a slice, in place.
#[derive(Clone, Debug)]
pub struct Selector<const N: usize = DEFAULT_OBSTACLE_CAPACITY> {
    set: ObstacleSet<N>,
    ranker: Ranker<N>,
}

impl<const N: usize> Selector<N> {
    /// An empty selection for a vehicle at `p` moving at `v` (NED, m and m/s); `delta1`
    /// (m²) classifies dropped points as near.
    pub fn new(ranking: Ranking, delta1: f32, p: &Vec3, v: &Vec3) -> Self {
        Selector { set: ObstacleSet::new(), ranker: Ranker::new(ranking, delta1, p, v) }
    }

    /// [`Self::new`] for a caller that reads only the set: the same points in the same
    /// slots, the report without the dropped points (`dropped` and `dropped_near` 0,
    /// `min_dropped_key` +∞), so a dropped or evicted point costs no bookkeeping.
    pub fn set_only(ranking: Ranking, delta1: f32, p: &Vec3, v: &Vec3) -> Self {
        let mut s = Self::new(ranking, delta1, p, v);
        s.ranker.count_drops = false;
        s
    }

    /// The points kept so far.
    pub fn set(&self) -> &ObstacleSet<N> {
        &self.set
    }

    /// The report so far (`kept` = points stored now).
    pub fn report(&self) -> SetReport {
        self.ranker.report(self.set.len())
    }

    /// The kept points and the report.
    pub fn finish(self) -> (ObstacleSet<N>, SetReport) {
        let rep = self.report();
        (self.set, rep)
    }

    /// Offer one point. Bounded: O(1) below capacity or when it cannot enter, else two
    /// O(N) scans (plus one O(N²) tier assignment when the set first overflows).
    pub fn offer(&mut self, o: &ObstaclePoint) -> Offer {
        self.ranker.offer(&mut self.set, o)
    }

    /// [`Self::offer`] of `ObstaclePoint { point, velocity, id, normal: None }`, the point
    /// built only when it is stored (a memory's cells: most are not).
    #[inline(always)]
    pub fn offer_point(&mut self, point: &Vec3, velocity: Option<&Vec3>, id: u16) -> Offer {
        let r = &mut self.ranker;
        let (key, h) = key_parts(r.ranking, &r.p, &r.v, point, velocity);
        let point_ok = plausible(point) && velocity.is_none_or(plausible);
        let make = || ObstaclePoint { point: *point, velocity: velocity.copied(), id, normal: None };
        r.offer_ranked(&mut self.set, key, h, point_ok, id, make)
    }
}

/// Replace the contents of `set` with the points of `offered` selected by `ranking`
/// for a vehicle at `p` moving at `v` (NED, m and m/s); `delta1` (m²) classifies dropped
/// points as near. In place; see the module docs for the policy and the bound.
pub fn select<const N: usize>(
    set: &mut ObstacleSet<N>,
    ranking: Ranking,
    delta1: f32,
    p: &Vec3,
    v: &Vec3,
    offered: &[ObstaclePoint],
) -> SetReport {
    set.clear();
    let mut r = Ranker::<N>::new(ranking, delta1, p, v);
    for o in offered {
        r.offer(set, o);
    }
    r.report(set.len())
}

#[inline]
fn drop_point(rep: &mut SetReport, key: f32, h: f32, delta1: f32) {
    rep.dropped = rep.dropped.saturating_add(1);
    if h <= delta1 {
        rep.dropped_near = rep.dropped_near.saturating_add(1);
    }
    if key < rep.min_dropped_key {
        rep.min_dropped_key = key;
    }
}

/// Slots per block of the cached worst entries ([`Ranker`]'s `block_worst`).
const BLOCK: usize = 8;

/// Index of the first worst entry (`0` for an empty slice), by integer comparisons.
#[inline]
fn worst_index(ranks: &[Rank]) -> usize {
    let Some(&Rank(first)) = ranks.first() else { return 0 };
    let (mut w, mut ow) = (0, first);
    for (i, &Rank(o)) in ranks.iter().enumerate().skip(1) {
        if o > ow {
            (w, ow) = (i, o);
        }
    }
    w
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::obstacle::InsertOutcome;
    use std::vec;

    fn pt(x: f32, y: f32, id: u16) -> ObstaclePoint {
        ObstaclePoint::fixed(Vec3::new(x, y, 0.0), id)
    }

    fn ids<const N: usize>(s: &ObstacleSet<N>) -> std::vec::Vec<u16> {
        s.as_slice().iter().map(|o| o.id).collect()
    }

    /// A small deterministic generator (xorshift) for the randomised checks.
    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> f32 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            (self.0 >> 40) as f32 / (1u64 << 24) as f32
        }
    }

    /// The integer keep order agrees with `worse_than` on finite keys (negative barrier
    /// values, ±0, equal keys, both tiers).
    #[test]
    fn rank_order_agrees_with_worse_than() {
        let mut rng = Rng(0x5eed_0019);
        let mut keys = vec![0.0f32, -0.0, 1.0, -1.0, f32::MIN_POSITIVE, -f32::MIN_POSITIVE, 1e-40, -1e-40];
        keys.extend((0..200).map(|_| (rng.next() - 0.5) * 10.0));
        keys.extend([f32::MAX, f32::MIN, 3.0, 3.0]);
        for &a in &keys {
            for &b in &keys {
                for (ta, tb) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
                    let (ra, rb) = (Rank::new(ta, a), Rank::new(tb, b));
                    let want = ta > tb || (ta == tb && a > b);
                    assert_eq!(ra.worse_than(&rb), want, "{ta} {a} {tb} {b}");
                    assert_eq!(ra.key_bits() < rb.key_bits(), a < b, "{a} {b}");
                    assert_eq!(ra.key_bits() == rb.key_bits(), a == b, "{a} {b}");
                    assert_eq!((ra.tier(), ra.with_tier(1).tier()), (ta, 1));
                }
            }
        }
    }

    #[test]
    fn below_capacity_everything_is_kept_in_order() {
        let mut s = ObstacleSet::<4>::new();
        let pts = [pt(3.0, 0.0, 3), pt(1.0, 0.0, 1), pt(2.0, 0.0, 2)];
        let r = select(
            &mut s,
            Ranking::Critical { mu: 1.4, relative: true },
            0.1,
            &Vec3::zeros(),
            &Vec3::zeros(),
            &pts,
        );
        assert_eq!(ids(&s), vec![3, 1, 2]);
        assert_eq!((r.offered, r.kept, r.dropped, r.dropped_near), (3, 3, 0, 0));
        assert_eq!(r.min_dropped_key, f32::INFINITY);
    }

    #[test]
    fn nearest_ranking_equals_the_published_insert() {
        let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
        for _ in 0..200 {
            let n = (rng.next() * 40.0) as usize;
            let pts: std::vec::Vec<_> =
                (0..n).map(|i| pt(rng.next() * 4.0 - 2.0, rng.next() * 4.0 - 2.0, (i % 7) as u16)).collect();
            let p = Vec3::new(0.1, -0.2, 0.0);
            let mut a = ObstacleSet::<8>::new();
            let r = select(&mut a, Ranking::Nearest, 0.1, &p, &Vec3::new(1.0, 0.0, 0.0), &pts);
            let mut b = ObstacleSet::<8>::new();
            let mut dropped = 0;
            for o in &pts {
                if b.insert_nearest(&p, *o) == InsertOutcome::DroppedFarther {
                    dropped += 1;
                } else if n > 8 {
                    // ReplacedFarthest also drops one.
                }
            }
            assert_eq!(a.as_slice(), b.as_slice());
            assert_eq!(r.dropped as usize, n.saturating_sub(8));
            let _ = dropped;
        }
    }

    #[test]
    fn a_closing_wall_beats_nearer_points_beside_the_path() {
        // Vehicle at the origin flying +x at 0.3 m/s; 40 points 0.35 m to the side,
        // a wall point 0.5 m ahead (h = 0.25 − 1.4·0.5·0.3 = 0.04 < 0.1225).
        let mut pts = std::vec::Vec::new();
        for i in 0..40 {
            let a = i as f32 * 0.157;
            pts.push(ObstaclePoint::fixed(
                Vec3::new(0.02 * (i % 5) as f32, 0.35 * a.cos(), 0.35 * a.sin()),
                100 + i,
            ));
        }
        pts.push(pt(0.5, 0.0, 1));
        let v = Vec3::new(0.3, 0.0, 0.0);
        let mut s = ObstacleSet::<32>::new();
        let r = select(&mut s, Ranking::Critical { mu: 1.4, relative: true }, 0.1, &Vec3::zeros(), &v, &pts);
        assert!(ids(&s).contains(&1), "the wall was dropped");
        assert_eq!((r.kept, r.dropped), (32, 9));
        // Nearest-first drops it (it is farther than all 40).
        let mut n = ObstacleSet::<32>::new();
        select(&mut n, Ranking::Nearest, 0.1, &Vec3::zeros(), &v, &pts);
        assert!(!ids(&n).contains(&1));
    }

    #[test]
    fn every_obstacle_keeps_a_point_before_any_gets_a_second() {
        // Obstacle 7 offers 10 points, all nearer than obstacles 1..=3's single points.
        let mut pts: std::vec::Vec<_> = (0..10).map(|i| pt(0.3 + 0.01 * i as f32, 0.0, 7)).collect();
        pts.extend([pt(2.0, 0.0, 1), pt(0.0, 3.0, 2), pt(-4.0, 0.0, 3)]);
        let mut s = ObstacleSet::<5>::new();
        let r = select(
            &mut s,
            Ranking::Critical { mu: 1.0, relative: false },
            0.1,
            &Vec3::zeros(),
            &Vec3::zeros(),
            &pts,
        );
        let kept = ids(&s);
        for id in [1, 2, 3, 7] {
            assert!(kept.contains(&id), "{id} missing: {kept:?}");
        }
        // The fifth slot is obstacle 7's second most critical point.
        let sevens: std::vec::Vec<f32> =
            s.as_slice().iter().filter(|o| o.id == 7).map(|o| o.point.x).collect();
        assert_eq!(sevens.len(), 2);
        assert!(sevens.iter().all(|x| *x <= 0.31 + 1e-6), "{sevens:?}");
        assert_eq!(r.dropped, 8);
    }

    /// Brute force: sort by (tier, key, offer index) with tiers computed over all points.
    fn reference(
        ranking: Ranking,
        p: &Vec3,
        v: &Vec3,
        pts: &[ObstaclePoint],
        n: usize,
    ) -> std::vec::Vec<usize> {
        let keys: std::vec::Vec<f32> = pts.iter().map(|o| key_of(ranking, p, v, o).0).collect();
        let tiers = matches!(ranking, Ranking::Critical { .. });
        let tier = |i: usize| -> u8 {
            if !tiers {
                return 0;
            }
            // Tier 0 if no earlier point of the id has a key ≤ and no later one a key <.
            let better = pts.iter().enumerate().any(|(j, q)| {
                q.id == pts[i].id && j != i && (keys[j] < keys[i] || (keys[j] == keys[i] && j < i))
            });
            u8::from(better)
        };
        let mut idx: std::vec::Vec<usize> = (0..pts.len()).collect();
        idx.sort_by(|&a, &b| (tier(a), keys[a]).partial_cmp(&(tier(b), keys[b])).unwrap().then(a.cmp(&b)));
        idx.truncate(n);
        idx.sort_unstable();
        idx
    }

    #[test]
    fn the_kept_set_is_the_best_n_in_tier_then_key_order() {
        let mut rng = Rng(42);
        for case in 0..2000 {
            let m = (rng.next() * 60.0) as usize;
            let n_ids = 1 + (rng.next() * 20.0) as u16;
            let pts: std::vec::Vec<_> = (0..m)
                .map(|_| {
                    let mut o = ObstaclePoint::fixed(
                        Vec3::new(rng.next() * 6.0 - 3.0, rng.next() * 6.0 - 3.0, rng.next() * 2.0 - 1.0),
                        (rng.next() * n_ids as f32) as u16,
                    );
                    if rng.next() < 0.3 {
                        o.velocity = Some(Vec3::new(rng.next() - 0.5, rng.next() - 0.5, 0.0));
                    }
                    o
                })
                .collect();
            let v = Vec3::new(rng.next() * 2.0 - 1.0, rng.next() * 2.0 - 1.0, 0.0);
            let p = Vec3::new(0.0, 0.0, 0.0);
            let ranking = Ranking::Critical { mu: 0.5 + rng.next(), relative: case % 2 == 0 };
            let mut s = ObstacleSet::<8>::new();
            let r = select(&mut s, ranking, 0.3, &p, &v, &pts);
            let want: std::vec::Vec<ObstaclePoint> =
                reference(ranking, &p, &v, &pts, 8).iter().map(|&i| pts[i]).collect();
            let mut got: std::vec::Vec<ObstaclePoint> = s.as_slice().to_vec();
            let pos = |o: &ObstaclePoint| pts.iter().position(|q| q == o).unwrap();
            got.sort_by_key(pos);
            assert_eq!(got, want, "case {case}");
            assert_eq!(r.kept as usize + r.dropped as usize, m);
            // dropped_near counts the dropped points with h ≤ δ1.
            let near = pts
                .iter()
                .filter(|o| !got.contains(o))
                .filter(|o| key_of(ranking, &p, &v, o).1 <= 0.3)
                .count();
            assert_eq!(r.dropped_near as usize, near, "case {case}");
        }
    }

    /// The rank as first written: (tier, key) compared as numbers.
    #[derive(Clone, Copy, Debug)]
    struct RefRank {
        tier: u8,
        key: f32,
    }

    impl RefRank {
        fn worse_than(&self, o: &RefRank) -> bool {
            self.tier > o.tier || (self.tier == o.tier && self.key > o.key)
        }
    }

    /// The streaming selection as first written (a full sibling search and a full worst
    /// search per point, `worse_than` comparisons): the slots' contents and order and the
    /// report, for checking the cached searches against it.
    fn streaming_reference<const N: usize>(
        ranking: Ranking,
        delta1: f32,
        p: &Vec3,
        v: &Vec3,
        pts: &[ObstaclePoint],
    ) -> (std::vec::Vec<ObstaclePoint>, SetReport) {
        let first_worst = |ranks: &[RefRank]| {
            let mut w = 0;
            for (i, r) in ranks.iter().enumerate() {
                if r.worse_than(&ranks[w]) {
                    w = i;
                }
            }
            w
        };
        let mut set: std::vec::Vec<ObstaclePoint> = std::vec::Vec::new();
        let mut ranks: std::vec::Vec<RefRank> = std::vec::Vec::new();
        let mut rep = SetReport { min_dropped_key: f32::INFINITY, ..SetReport::default() };
        let mut tiered = false;
        let critical = matches!(ranking, Ranking::Critical { .. });
        for o in pts {
            let (key, h) = key_of(ranking, p, v, o);
            rep.offered += 1;
            if set.len() < N {
                set.push(*o);
                ranks.push(RefRank { tier: 0, key });
                continue;
            }
            if !tiered && critical {
                let tiers: std::vec::Vec<u8> = (0..N)
                    .map(|i| {
                        u8::from((0..N).any(|j| {
                            j != i
                                && set[j].id == set[i].id
                                && (ranks[j].key < ranks[i].key || (ranks[j].key == ranks[i].key && j < i))
                        }))
                    })
                    .collect();
                for (r, t) in ranks.iter_mut().zip(tiers) {
                    r.tier = t;
                }
            }
            tiered = true;
            let mut r = RefRank { tier: 0, key };
            if critical {
                if let Some(s) = (0..N).find(|&j| set[j].id == o.id && ranks[j].tier == 0) {
                    if key < ranks[s].key {
                        ranks[s].tier = 1;
                    } else {
                        r.tier = 1;
                    }
                }
            }
            let w = first_worst(&ranks);
            if !ranks[w].worse_than(&r) {
                drop_point(&mut rep, key, h, delta1);
                continue;
            }
            let (wk, wh) = key_of(ranking, p, v, &set[w]);
            drop_point(&mut rep, wk, wh, delta1);
            set[w] = *o;
            ranks[w] = r;
        }
        rep.kept = set.len() as u16;
        (set, rep)
    }

    fn check_against_reference<const N: usize>(
        case: usize,
        ranking: Ranking,
        p: &Vec3,
        v: &Vec3,
        pts: &[ObstaclePoint],
    ) {
        let mut s = ObstacleSet::<N>::new();
        let r = select(&mut s, ranking, 0.3, p, v, pts);
        let (want, want_rep) = streaming_reference::<N>(ranking, 0.3, p, v, pts);
        assert_eq!(s.as_slice(), &want[..], "case {case} N {N} {ranking:?}");
        assert_eq!(r, want_rep, "case {case} N {N} {ranking:?}");
        // The set-only selector: the same slots, the report without the dropped points.
        let mut only = Selector::<N>::set_only(ranking, 0.3, p, v);
        for o in pts {
            only.offer(o);
        }
        let (set, rep) = only.finish();
        assert_eq!(set.as_slice(), &want[..], "set_only: case {case} N {N} {ranking:?}");
        let uncounted = SetReport { dropped: 0, dropped_near: 0, min_dropped_key: f32::INFINITY, ..want_rep };
        assert_eq!(rep, uncounted, "set_only: case {case} N {N} {ranking:?}");
    }

    /// The selector with its cached searches gives the slots (contents and order) and the
    /// report of the streaming selection as first written: runs of one id (a memory's
    /// static cells), few and many ids, repeated points (equal keys), moving points.
    #[test]
    fn cached_searches_give_the_streaming_selection_slot_for_slot() {
        let mut rng = Rng(0x1919_0032);
        for case in 0..3000 {
            let m = (rng.next() * 150.0) as usize;
            let n_ids = 1 + (rng.next() * 12.0) as u16;
            let mut pts: std::vec::Vec<ObstaclePoint> = std::vec::Vec::new();
            while pts.len() < m {
                let id = if rng.next() < 0.6 { 0 } else { (rng.next() * n_ids as f32) as u16 };
                let run = 1 + (rng.next() * 10.0) as usize;
                for _ in 0..run {
                    if rng.next() < 0.1 && !pts.is_empty() {
                        let k = (rng.next() * pts.len() as f32) as usize % pts.len();
                        pts.push(pts[k]);
                        continue;
                    }
                    let mut o = ObstaclePoint::fixed(
                        Vec3::new(rng.next() * 6.0 - 3.0, rng.next() * 6.0 - 3.0, rng.next() * 2.0 - 1.0),
                        id,
                    );
                    if rng.next() < 0.2 {
                        o.velocity = Some(Vec3::new(rng.next() - 0.5, rng.next() - 0.5, 0.0));
                    }
                    pts.push(o);
                }
            }
            let v = Vec3::new(rng.next() * 2.0 - 1.0, rng.next() * 2.0 - 1.0, 0.0);
            let p = Vec3::new(0.1, -0.2, -1.0);
            for ranking in
                [Ranking::Critical { mu: 0.5 + rng.next(), relative: case % 2 == 0 }, Ranking::Nearest]
            {
                check_against_reference::<8>(case, ranking, &p, &v, &pts);
                // Several blocks of cached worst entries, the last one partial.
                check_against_reference::<20>(case, ranking, &p, &v, &pts);
                check_against_reference::<32>(case, ranking, &p, &v, &pts);
            }
        }
    }

    #[test]
    fn the_selector_says_what_it_did_with_each_point() {
        let mut s = Selector::<2>::new(
            Ranking::Critical { mu: 1.0, relative: false },
            0.1,
            &Vec3::zeros(),
            &Vec3::zeros(),
        );
        assert_eq!(s.offer(&pt(2.0, 0.0, 1)), Offer::Kept);
        assert_eq!(s.offer(&pt(3.0, 0.0, 2)), Offer::Kept);
        assert_eq!(s.offer(&pt(4.0, 0.0, 3)), Offer::Dropped);
        assert_eq!(s.offer(&pt(1.0, 0.0, 4)), Offer::Kept); // replaces id 2
        assert_eq!(s.offer(&pt(f32::NAN, 0.0, 5)), Offer::Rejected);
        assert_eq!(ids(s.set()), vec![1, 4]);
        let (set, r) = s.finish();
        assert_eq!(set.len(), 2);
        assert_eq!((r.offered, r.kept, r.dropped, r.rejected), (4, 2, 2, 1));
        assert_eq!(r.min_dropped_key, 9.0);
    }

    #[test]
    fn non_finite_points_are_rejected_not_ranked() {
        let mut s = ObstacleSet::<2>::new();
        let pts = [pt(f32::NAN, 0.0, 1), pt(1.0, 0.0, 2), pt(f32::INFINITY, 0.0, 3)];
        let r = select(
            &mut s,
            Ranking::Critical { mu: 1.4, relative: true },
            0.1,
            &Vec3::zeros(),
            &Vec3::zeros(),
            &pts,
        );
        assert_eq!(ids(&s), vec![2]);
        assert_eq!((r.rejected, r.offered, r.dropped), (2, 1, 0));
        let r =
            select(&mut s, Ranking::Nearest, 0.1, &Vec3::new(f32::NAN, 0.0, 0.0), &Vec3::zeros(), &pts[1..2]);
        assert!(s.is_empty());
        assert_eq!(r.rejected, 1);
    }
}
