//! A* on the replanner's grid (Hart, Nilsson & Raphael 1968, "A Formal Basis for the
//! Heuristic Determination of Minimum Cost Paths"): 8-connected, octile costs (10 straight,
//! 14 diagonal, in tenths of a cell), the octile distance as the heuristic (admissible and
//! consistent, so every expanded cell is closed once), no corner cutting (a diagonal step
//! needs both orthogonal neighbours passable).
//!
//! **Bounds.** At most `max_expansions` cells are expanded (≤ [`CELLS`]) and the open list
//! holds at most [`OPEN_CAP`] entries (a binary heap of packed `f · 4096 + cell` keys, stale
//! entries skipped when popped); reaching either is [`SearchResult::Budget`], a defined
//! result. Memory: 2 B of cost + 1 B of parent per cell, 4 B per open entry (≈ 20 KiB).
//!
//! May import: the parent module's [`super::grid`].

use heapless::binary_heap::{BinaryHeap, Min};

use super::grid::{Rows, CELLS, GRID};

/// Open-list capacity (entries).
pub const OPEN_CAP: usize = 2048;

const UNSEEN: u16 = u16::MAX;
const NO_PARENT: u8 = u8::MAX;
/// Neighbour steps (row, column, cost in tenths of a cell).
const STEPS: [(i32, i32, u16); 8] =
    [(1, 0, 10), (-1, 0, 10), (0, 1, 10), (0, -1, 10), (1, 1, 14), (1, -1, 14), (-1, 1, 14), (-1, -1, 14)];

/// What one search found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SearchResult {
    /// The goal was reached after this many expansions; the path is read with
    /// [`Search::parent`] from the goal.
    Found(u32),
    /// Every cell reachable from the start was expanded (this many): the goal is not reachable.
    NoPath(u32),
    /// The expansion cap or the open-list capacity was reached first.
    Budget,
}

/// The search's buffers (reused between searches; no allocation).
#[derive(Clone, Debug)]
pub struct Search {
    g: [u16; CELLS],
    parent: [u8; CELLS],
    closed: Rows,
    open: BinaryHeap<u32, Min, OPEN_CAP>,
}

impl Search {
    /// Every buffer zero, as a constant (a `static` of it needs no start-up copy and no
    /// stack): as good as [`Search::default`], since every search resets its buffers first.
    pub const ZEROED: Search =
        Search { g: [0; CELLS], parent: [0; CELLS], closed: [0; GRID], open: BinaryHeap::new() };
}

impl Default for Search {
    fn default() -> Self {
        Search { g: [UNSEEN; CELLS], parent: [NO_PARENT; CELLS], closed: [0; GRID], open: BinaryHeap::new() }
    }
}

fn octile(a: (usize, usize), b: (usize, usize)) -> u32 {
    let (dx, dy) = (a.0.abs_diff(b.0) as u32, a.1.abs_diff(b.1) as u32);
    10 * dx.max(dy) + 4 * dx.min(dy)
}

impl Search {
    /// Search from `start` to `goal` (row, column) through the cells `passable(i, j)`
    /// accepts (the start need not be), expanding at most `max_expansions` cells.
    pub fn run(
        &mut self,
        start: (usize, usize),
        goal: (usize, usize),
        passable: impl Fn(usize, usize) -> bool,
        max_expansions: u32,
    ) -> SearchResult {
        // In place: no 8 KiB array value on the stack (the firmware's planner task).
        self.g.fill(UNSEEN);
        self.parent.fill(NO_PARENT);
        self.closed.fill(0);
        self.open.clear();
        if start.0 >= GRID || start.1 >= GRID || goal.0 >= GRID || goal.1 >= GRID {
            return SearchResult::NoPath(0);
        }
        let s = start.0 * GRID + start.1;
        self.g[s] = 0;
        if self.open.push(octile(start, goal) << 12 | s as u32).is_err() {
            return SearchResult::Budget;
        }
        let mut expanded = 0u32;
        while let Some(key) = self.open.pop() {
            let c = (key & 0xFFF) as usize;
            let (i, j) = (c / GRID, c % GRID);
            if self.closed[i] & (1u64 << j) != 0 {
                continue;
            }
            if (i, j) == goal {
                return SearchResult::Found(expanded);
            }
            if expanded >= max_expansions.min(CELLS as u32) {
                return SearchResult::Budget;
            }
            expanded += 1;
            self.closed[i] |= 1u64 << j;
            let ok = |di: i32, dj: i32| {
                let (ni, nj) = (i as i32 + di, j as i32 + dj);
                (0..GRID as i32).contains(&ni)
                    && (0..GRID as i32).contains(&nj)
                    && passable(ni as usize, nj as usize)
            };
            for (d, &(di, dj, cost)) in STEPS.iter().enumerate() {
                if !ok(di, dj) || (di != 0 && dj != 0 && !(ok(di, 0) && ok(0, dj))) {
                    continue;
                }
                let (ni, nj) = ((i as i32 + di) as usize, (j as i32 + dj) as usize);
                let n = ni * GRID + nj;
                let g = self.g[c].saturating_add(cost);
                if self.closed[ni] & (1u64 << nj) != 0 || g >= self.g[n] {
                    continue;
                }
                self.g[n] = g;
                self.parent[n] = d as u8;
                let f = g as u32 + octile((ni, nj), goal);
                if self.open.push(f << 12 | n as u32).is_err() {
                    return SearchResult::Budget;
                }
            }
        }
        SearchResult::NoPath(expanded)
    }

    /// The cell the found path came from into cell (row, column); `None` at the start.
    pub fn parent(&self, i: usize, j: usize) -> Option<(usize, usize)> {
        let d = *self.parent.get(i * GRID + j)?;
        let &(di, dj, _) = STEPS.get(d as usize)?;
        Some(((i as i32 - di) as usize, (j as i32 - dj) as usize))
    }

    /// Path cost to cell (row, column) in tenths of a cell (`None`: not reached).
    pub fn cost(&self, i: usize, j: usize) -> Option<u16> {
        self.g.get(i * GRID + j).copied().filter(|&g| g != UNSEEN)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn octile_costs_and_walls() {
        let mut s = Search::default();
        let free = |_: usize, _: usize| true;
        assert!(matches!(s.run((0, 0), (3, 5), free, 4096), SearchResult::Found(n) if n <= 20));
        assert_eq!(s.cost(3, 5), Some(3 * 14 + 2 * 10));
        assert_eq!(steps_back(&s, 3, 5), 5, "three diagonal and two straight steps");
        // A wall on row 10 with one gap at column 40.
        let wall = |i: usize, j: usize| !(i == 10 && j != 40);
        assert!(matches!(s.run((5, 5), (15, 5), wall, 4096), SearchResult::Found(_)));
        let mut c = (15, 5);
        let mut through_gap = false;
        for _ in 0..CELLS {
            through_gap |= c == (10, 40);
            match s.parent(c.0, c.1) {
                Some(p) => c = p,
                None => break,
            }
        }
        assert!(through_gap && c == (5, 5));
        let closed = |i: usize, _: usize| i != 10;
        assert!(matches!(s.run((5, 5), (15, 5), closed, 4096), SearchResult::NoPath(n) if n == 10 * 64));
        assert_eq!(s.run((5, 5), (15, 5), closed, 100), SearchResult::Budget);
    }

    /// Steps of the found path back from cell (row, column) to the start.
    fn steps_back(s: &Search, i: usize, j: usize) -> u32 {
        let mut n = 0;
        let mut c = (i, j);
        while let Some(p) = s.parent(c.0, c.1) {
            c = p;
            n += 1;
        }
        n
    }
}
