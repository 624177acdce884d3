//! Track ids of the obstacles in view: the `u16` ids the proximity report gives the flight
//! controller, as a perception system's tracker hands them out.
//!
//! The flight controller's obstacle ids are `u16` (like MAVLink OBSTACLE_DISTANCE_3D's
//! `obstacle_id`, whose 65 535 is [`CLEAR_ID`], "no obstacle"), while a scene may hold more
//! obstacles than that: the scene index cast to `u16` would wrap, and two different obstacles in
//! view could share an id (obstacle `i` and `i + 65 536`). [`TrackIds`] keeps a bounded table of
//! the obstacles in view instead:
//! * an obstacle keeps its id while it stays in view (seen in every sensing pass);
//! * no two obstacles in view share an id, and no id is [`CLEAR_ID`];
//! * an obstacle gets its scene index modulo 65 535 when that id is free, else the next free
//!   one, so in a scene of at most 65 535 obstacles the id IS the scene index (the reports and
//!   every result of such scenes are those of the plain index);
//! * an obstacle missing from a pass loses its id when the next pass starts (free for others
//!   from then on);
//! * with 65 535 ids held at once (the table is full) a further obstacle gets no id and is
//!   not reported; [`TrackIds::refused`] counts them.
//!
//! Owns only the id table; imports `parapet-core`'s wire constant, std and foldhash (the hasher).

use std::collections::HashMap;

/// The maps' hasher: foldhash with a fixed seed (SipHash's resistance to chosen keys is not
/// needed for scene indices and ids; it cost ~30 M instructions in the office flight).
type Fast = foldhash::fast::FixedState;

use parapet_core::wire::ids::CLEAR_ID;

/// Number of usable ids: `0 ..= 65 534` (65 535 is [`CLEAR_ID`]).
pub const ID_COUNT: usize = CLEAR_ID as usize;

/// The table (see the module doc). Call [`begin_pass`](Self::begin_pass) once per sensing pass,
/// then [`id`](Self::id) for each obstacle in view.
#[derive(Clone, Debug, Default)]
pub struct TrackIds {
    /// Obstacle (scene index) → its id and the pass it was last seen in.
    by_obstacle: HashMap<usize, (u16, u64), Fast>,
    /// Id → the obstacle holding it.
    owner: HashMap<u16, usize, Fast>,
    /// Current pass (starts at 1 with the first [`begin_pass`](Self::begin_pass)).
    pass: u64,
    /// Obstacles in view that got no id because all [`ID_COUNT`] ids were held.
    refused: u64,
}

impl TrackIds {
    pub fn new() -> TrackIds {
        TrackIds::default()
    }

    /// Starts a sensing pass: the obstacles that were not seen in the previous pass leave view
    /// and free their ids.
    pub fn begin_pass(&mut self) {
        let last = self.pass;
        let owner = &mut self.owner;
        self.by_obstacle.retain(|_, &mut (id, seen)| {
            let keep = seen == last;
            if !keep {
                owner.remove(&id);
            }
            keep
        });
        self.pass += 1;
    }

    /// The id of obstacle `index` (scene index), seen in this pass; `None` when all ids are held
    /// by other obstacles in view.
    pub fn id(&mut self, index: usize) -> Option<u16> {
        if let Some(e) = self.by_obstacle.get_mut(&index) {
            e.1 = self.pass;
            return Some(e.0);
        }
        if self.owner.len() >= ID_COUNT {
            self.refused += 1;
            return None;
        }
        // The table is not full, so a free id is found within ID_COUNT probes.
        let mut id = (index % ID_COUNT) as u16;
        while self.owner.contains_key(&id) {
            id = if usize::from(id) + 1 == ID_COUNT { 0 } else { id + 1 };
        }
        self.owner.insert(id, index);
        self.by_obstacle.insert(index, (id, self.pass));
        Some(id)
    }

    /// The obstacle (scene index) holding `id`, if any (the report's `active_obstacle` back to
    /// the scene).
    pub fn obstacle(&self, id: u16) -> Option<usize> {
        self.owner.get(&id).copied()
    }

    /// Obstacles in view that got no id so far (see the module doc).
    pub fn refused(&self) -> u64 {
        self.refused
    }

    /// Obstacles holding an id now.
    pub fn len(&self) -> usize {
        self.owner.len()
    }

    pub fn is_empty(&self) -> bool {
        self.owner.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One pass over `seen`: their ids.
    fn pass(t: &mut TrackIds, seen: &[usize]) -> Vec<Option<u16>> {
        t.begin_pass();
        seen.iter().map(|&i| t.id(i)).collect()
    }

    #[test]
    fn small_scenes_get_their_index() {
        let mut t = TrackIds::new();
        assert_eq!(pass(&mut t, &[0, 5, 65_534]), [Some(0), Some(5), Some(65_534)]);
        assert_eq!(pass(&mut t, &[65_534, 7]), [Some(65_534), Some(7)]);
        assert_eq!(pass(&mut t, &[7]), [Some(7)]);
        // 0 and 5 were missing from the second pass: freed when the third started.
        assert_eq!((t.len(), t.obstacle(5), t.obstacle(0), t.obstacle(7)), (2, None, None, Some(7)));
    }

    #[test]
    fn indices_65536_apart_in_view_get_different_ids_stable_while_in_view() {
        let mut t = TrackIds::new();
        let (a, b, c) = (3usize, 3 + 65_536, 3 + 65_535);
        let first = pass(&mut t, &[a, b, c]);
        assert_eq!(first[0], Some(3));
        let ids: Vec<u16> = first.iter().map(|x| x.unwrap()).collect();
        assert!(ids[0] != ids[1] && ids[1] != ids[2] && ids[0] != ids[2], "{ids:?}");
        assert!(ids.iter().all(|&i| i != CLEAR_ID));
        // Stable while in view, whatever the order of the report.
        for _ in 0..3 {
            assert_eq!(pass(&mut t, &[c, b, a]), [Some(ids[2]), Some(ids[1]), Some(ids[0])]);
        }
        // a leaves view: b keeps its id; from the pass after, a new obstacle with a's preferred
        // id takes it.
        assert_eq!(pass(&mut t, &[b, c]), [Some(ids[1]), Some(ids[2])]);
        assert_eq!(pass(&mut t, &[b, c, 3 + 2 * 65_535]), [Some(ids[1]), Some(ids[2]), Some(3)]);
        assert_eq!(t.obstacle(3), Some(3 + 2 * 65_535));
    }

    #[test]
    fn never_two_in_view_with_one_id_and_never_clear_id() {
        // Indices that all want id 65 534 (the last one) or 0: probing wraps past 65 534 to 0.
        let mut t = TrackIds::new();
        let seen: Vec<usize> = (0..50).map(|k| 65_534 + k * ID_COUNT).chain([0, 1]).collect();
        let ids: Vec<u16> = pass(&mut t, &seen).into_iter().map(Option::unwrap).collect();
        let mut sorted = ids.clone();
        sorted.sort_unstable();
        sorted.dedup();
        assert_eq!(sorted.len(), ids.len(), "{ids:?}");
        assert!(ids.iter().all(|&i| i != CLEAR_ID));
        assert_eq!(ids[0], 65_534);
    }

    #[test]
    fn a_full_table_refuses_and_frees_when_obstacles_leave() {
        let mut t = TrackIds::new();
        let all: Vec<usize> = (0..ID_COUNT).map(|i| i + 1_000_000).collect();
        let ids = pass(&mut t, &all);
        assert!(ids.iter().all(Option::is_some));
        assert_eq!(t.id(5_000_000), None);
        assert_eq!(t.refused(), 1);
        // Next pass only one of them is seen: the table is still full during that pass (5,000,000
        // refused again), the others' ids are freed when the pass after starts.
        assert_eq!(pass(&mut t, &[all[10], 5_000_000]), [ids[10], None]);
        assert_eq!(pass(&mut t, &[all[10], 5_000_000]), [ids[10], Some((5_000_000 % ID_COUNT) as u16)]);
        assert_eq!((t.len(), t.refused()), (2, 2));
    }
}
