//! Regions of a binary mask: holes filled, the largest connected component, and the flood
//! fill both are made of.

use ndarray::Array2;
use std::collections::VecDeque;

/// Foreground plus every background region not connected to the image border.
pub fn fill_holes(foreground: &Array2<bool>) -> Array2<bool> {
    let (h, w) = foreground.dim();
    let mut outside = Array2::from_elem((h, w), false);
    let mut queue = VecDeque::new();
    for (p, &fg) in foreground.indexed_iter() {
        if (p.0 == 0 || p.1 == 0 || p.0 == h - 1 || p.1 == w - 1) && !fg {
            outside[p] = true;
            queue.push_back(p);
        }
    }
    flood(&mut queue, (h, w), |p| {
        let admit = !foreground[p] && !outside[p];
        outside[p] |= admit;
        admit
    });
    outside.mapv(|o| !o)
}

/// The largest 4-connected component of `mask`.
pub fn largest_component(mask: &Array2<bool>) -> Array2<bool> {
    let mut label = Array2::<u32>::zeros(mask.dim());
    let mut sizes = vec![0usize];
    for start in mask.indexed_iter().filter(|(_, m)| **m).map(|(p, _)| p) {
        if label[start] != 0 {
            continue;
        }
        let id = sizes.len() as u32;
        label[start] = id;
        let mut size = 1;
        flood(&mut VecDeque::from([start]), mask.dim(), |p| {
            let admit = mask[p] && label[p] == 0;
            if admit {
                label[p] = id;
                size += 1;
            }
            admit
        });
        sizes.push(size);
    }
    let best = (1..sizes.len()).max_by_key(|&i| sizes[i]).unwrap_or(0) as u32;
    label.mapv(|l| l == best && best != 0)
}

/// Breadth-first flood over 4-neighbours; `visit` marks a pixel and says whether to enter it.
pub fn flood(
    queue: &mut VecDeque<(usize, usize)>,
    (h, w): (usize, usize),
    mut visit: impl FnMut((usize, usize)) -> bool,
) {
    while let Some((y, x)) = queue.pop_front() {
        let neighbours = [
            (y.wrapping_sub(1), x),
            (y + 1, x),
            (y, x.wrapping_sub(1)),
            (y, x + 1),
        ];
        for p in neighbours {
            if p.0 < h && p.1 < w && visit(p) {
                queue.push_back(p);
            }
        }
    }
}
