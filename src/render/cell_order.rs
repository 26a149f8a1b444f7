//! A visibility order of the shell's cells for one eye, back to front: what the real-time
//! pipeline's per-view order draws by ([`crate::scene::transparency::CellOrder::PerView`]).
//!
//! MPVO with the non-convex heuristic (Williams' MPVONC; the semi-transparent 3D textures
//! paper uses its successor SXMPVO). Across every face two cells share, the cell on the far
//! side from the eye must be drawn before the near one: the eye lies outside the far cell's
//! plane of that face. Those constraints are sorted topologically, and whenever several
//! cells are free to go next, the one whose centroid is farthest from the eye goes first:
//! that orders the cells of separate parts of a non-convex shell (which share no face) by
//! distance, which is right unless one part reaches behind another.
//!
//! The constraints can form a cycle (three or more cells that each hide part of the next;
//! rare in a shell of thin prisms, but possible near grazing views). Then no cell is free:
//! the farthest remaining cell is drawn next regardless, its unmet constraints dropped, and
//! the break counted ([`ViewOrder::cycles_broken`]). Where a cycle is broken, or a part
//! reaches behind another, compositing in this order is wrong by the cells' overlap on
//! screen; the per-pixel sorted list never is.

use glam::DVec3;
use std::cmp::Ordering;
use std::collections::{BinaryHeap, HashMap};

/// A drawing order and how it was reached.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ViewOrder {
    /// Cell indices, back to front.
    pub order: Vec<u32>,
    /// Times no cell was free and a constraint was dropped.
    pub cycles_broken: usize,
}

/// For each cell, the cell sharing each of its faces (face f leaves out corner f), if any:
/// faces are matched by their three corners, bit for bit (neighbouring cells compute shared
/// corners from the same shell points).
pub fn face_neighbours(corners: &[[DVec3; 4]]) -> Vec<[Option<u32>; 4]> {
    let key = |c: &[DVec3; 4], f: usize| {
        let mut k: Vec<[u64; 3]> = (0..4)
            .filter(|&i| i != f)
            .map(|i| c[i].to_array().map(f64::to_bits))
            .collect();
        k.sort_unstable();
        [k[0], k[1], k[2]]
    };
    let mut first: HashMap<[[u64; 3]; 3], (u32, usize)> = HashMap::new();
    let mut neighbours = vec![[None; 4]; corners.len()];
    for (cell, c) in corners.iter().enumerate() {
        for f in 0..4 {
            if let Some((other, g)) = first.remove(&key(c, f)) {
                neighbours[cell][f] = Some(other);
                neighbours[other as usize][g] = Some(cell as u32);
            } else {
                first.insert(key(c, f), (cell as u32, f));
            }
        }
    }
    neighbours
}

/// Sorts cells `0..distance.len()` so that for every pair (a, b) in `behind` (a must be
/// drawn before b) a comes first, taking the farthest free cell each time, and breaking
/// cycles by taking the farthest remaining cell.
pub fn far_first(distance: &[f64], behind: &[(u32, u32)]) -> ViewOrder {
    let n = distance.len();
    let mut after: Vec<Vec<u32>> = vec![Vec::new(); n];
    let mut waiting = vec![0usize; n];
    for &(a, b) in behind {
        after[a as usize].push(b);
        waiting[b as usize] += 1;
    }
    // Farthest first, ties by index.
    #[derive(PartialEq)]
    struct Far(f64, u32);
    impl Eq for Far {}
    impl PartialOrd for Far {
        fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
            Some(self.cmp(other))
        }
    }
    impl Ord for Far {
        fn cmp(&self, other: &Self) -> Ordering {
            self.0.total_cmp(&other.0).then(other.1.cmp(&self.1))
        }
    }
    let mut free: BinaryHeap<Far> = (0..n as u32)
        .filter(|&c| waiting[c as usize] == 0)
        .map(|c| Far(distance[c as usize], c))
        .collect();
    // Every cell by distance, for breaking cycles.
    let mut by_distance: Vec<u32> = (0..n as u32).collect();
    by_distance
        .sort_unstable_by(|&a, &b| Far(distance[b as usize], b).cmp(&Far(distance[a as usize], a)));
    let mut next_far = 0;
    let mut done = vec![false; n];
    let mut out = ViewOrder {
        order: Vec::with_capacity(n),
        cycles_broken: 0,
    };
    while out.order.len() < n {
        let cell = match free.pop() {
            Some(Far(_, c)) if !done[c as usize] => c,
            Some(_) => continue,
            None => {
                while done[by_distance[next_far] as usize] {
                    next_far += 1;
                }
                out.cycles_broken += 1;
                by_distance[next_far]
            }
        };
        done[cell as usize] = true;
        out.order.push(cell);
        for &b in &after[cell as usize] {
            let w = &mut waiting[b as usize];
            *w = w.saturating_sub(1);
            if *w == 0 && !done[b as usize] {
                free.push(Far(distance[b as usize], b));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Constraints win over distance; among free cells the farthest goes first.
    #[test]
    fn constraints_come_before_distance() {
        // 0 is nearest but must precede 2; 1 is farthest.
        let o = far_first(&[1.0, 3.0, 2.0], &[(0, 2)]);
        assert_eq!(o.order, [1, 0, 2]);
        assert_eq!(o.cycles_broken, 0);
    }

    /// A three-cycle 0 → 1 → 2 → 0 is broken once, at the farthest cell, and every cell
    /// appears once.
    #[test]
    fn a_cycle_is_broken_at_the_farthest_cell() {
        let o = far_first(&[1.0, 5.0, 3.0, 9.0], &[(0, 1), (1, 2), (2, 0)]);
        assert_eq!(o.cycles_broken, 1);
        // 3 is free; then 1, the farthest of the cycle, then 2 (freed by 1), then 0.
        assert_eq!(o.order, [3, 1, 2, 0]);
    }

    /// Two tetrahedra sharing a face are each other's neighbours across it, and nowhere
    /// else.
    #[test]
    fn shared_faces_are_matched() {
        let a = [DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z];
        let b = [DVec3::X, DVec3::ZERO, DVec3::Y, -DVec3::Z];
        let n = face_neighbours(&[a, b]);
        assert_eq!(n[0], [None, None, None, Some(1)]);
        assert_eq!(n[1], [None, None, None, Some(0)]);
    }
}
