//! A visibility order of the shell's cells for one view, back to front: what the real-time
//! pipeline's per-view orders draw by ([`crate::medium_settings::CellOrder`]).
//!
//! Both orders start from MPVO's constraints: across every face two cells share, the cell on
//! the far side from the eye must be drawn before the near one (the eye lies outside the far
//! cell's plane of that face). A non-convex mesh (a torus's shell, a wavy surface seen at a
//! grazing angle) also hides cells behind others across gaps of empty space, which no shared
//! face relates:
//! - **SXMPVO** ([`ViewSort::Sxmpvo`], Cook, Max, Silva and Williams 2004; the semi-transparent
//!   3D textures paper's choice) finds those relations in image space: every boundary face
//!   (a face no other cell shares) is cast through every pixel centre it covers, and per pixel,
//!   wherever the ray leaves the mesh through one cell and next enters it through another,
//!   the entered cell is behind the left one ([`gap_constraints`]). Along every pixel's ray
//!   each cell is then related to the next one it crosses, so the order is exact at every
//!   pixel centre unless the constraints form a cycle.
//! - **MPVONC** ([`ViewSort::Mpvonc`], Williams' non-convex heuristic) adds no relation
//!   across gaps and instead takes, whenever several cells are free to go next, the one whose
//!   centroid is farthest from the eye: cheaper, and wrong where one part of the mesh reaches
//!   behind another.
//!
//! Both sort their constraints topologically ([`far_first`]), the farthest free cell first.
//! The constraints can form a cycle (three or more cells that each hide part of the next;
//! rare in a shell of thin prisms, possible near grazing views). Then no cell is free: the
//! farthest remaining cell is drawn next regardless, its unmet constraints dropped, and the
//! break counted ([`ViewOrder::cycles_broken`]); the paper suggests clipping the cells
//! instead. Where a cycle is broken, compositing in this order is wrong by the cells' overlap
//! on screen; the per-pixel sorted list never is.

use glam::DVec3;
use rayon::prelude::*;
use std::cmp::Ordering;
use std::collections::{BinaryHeap, HashMap};

/// How a per-view order relates cells that share no face.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ViewSort {
    /// Per pixel, across every gap between the mesh's boundary faces (exact at pixel
    /// centres).
    Sxmpvo,
    /// Not at all: the farthest centroid first among cells free to go.
    Mpvonc,
}

/// Where a pixel's ray crosses a boundary face of the mesh (a face of one cell only).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoundaryFragment {
    /// The pixel, as `y · width + x`.
    pub pixel: u32,
    /// Ray parameter of the crossing.
    pub t: f64,
    /// The cell whose face it is.
    pub cell: u32,
    /// Whether the ray leaves the mesh there (the face's outward normal points along it).
    pub leaving: bool,
}

/// Relative gap below which a ray leaving the mesh and entering it again is taken to touch
/// it only (a silhouette edge where two boundary faces meet), not to cross empty space.
const MIN_GAP: f64 = 1e-9;

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

/// SXMPVO's constraints across gaps, as (behind, in front) pairs, sorted and without
/// repeats: per pixel, wherever the ray leaves the mesh through one cell's boundary face and
/// next enters it through another's (further than [`MIN_GAP`] of the distance on), the
/// entered cell is behind the one left. `fragments` may come in any order.
pub fn gap_constraints(mut fragments: Vec<BoundaryFragment>) -> Vec<(u32, u32)> {
    // By pixel, then along the ray; where a ray leaves and enters at one point, leaving
    // first.
    fragments.par_sort_unstable_by(|a, b| {
        (a.pixel.cmp(&b.pixel))
            .then(a.t.total_cmp(&b.t))
            .then(b.leaving.cmp(&a.leaving))
    });
    let mut behind: Vec<(u32, u32)> = fragments
        .windows(2)
        .filter(|w| {
            let (left, entered) = (w[0], w[1]);
            left.pixel == entered.pixel
                && left.leaving
                && !entered.leaving
                && entered.t - left.t > MIN_GAP * entered.t.abs()
        })
        .map(|w| (w[1].cell, w[0].cell))
        .collect();
    behind.par_sort_unstable();
    behind.dedup();
    behind
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

    /// Along one pixel's ray: enter cell 4, leave it, enter 7 beyond a gap, leave, enter
    /// 9 where the ray touched the mesh without a gap. Only the gap relates two cells.
    #[test]
    fn gaps_relate_the_cell_left_and_the_cell_entered() {
        let f = |pixel, t, cell, leaving| BoundaryFragment {
            pixel,
            t,
            cell,
            leaving,
        };
        let fragments = vec![
            f(3, 5.0, 7, false),
            f(3, 1.0, 4, false),
            f(3, 6.0, 7, true),
            f(3, 2.0, 4, true),
            f(3, 6.0, 9, false),
            // Another pixel's fragment between them in t relates nothing here.
            f(8, 3.0, 1, false),
            // The same gap seen from a second pixel: one pair.
            f(5, 2.5, 4, true),
            f(5, 5.5, 7, false),
        ];
        assert_eq!(gap_constraints(fragments), [(7, 4)]);
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
