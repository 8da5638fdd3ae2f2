//! The candidate search: edge points of the working copy vote for the centres along their
//! gradient lines, radius bin by radius bin; the best peaks, each with the radii at which most
//! of its circumference has an edge pointing at it, are the rough circles that
//! [`super::find_spheres`] refines.

use super::{UNCUT, length, quantile};
use crate::image::circle::Circle;
use crate::util::parallel::{self, in_parts};
use ndarray::{Array2, ArrayView2};
use std::sync::atomic::{AtomicBool, Ordering};

/// Candidate centres examined, and radii per centre.
const CANDIDATES: usize = 16;
const RADII_PER_CENTRE: usize = 3;

/// The rough circles (full-image coordinates) and their uncertainty from the vote over
/// `edges` of a working copy `dims` at `scale`, between `radii` (working pixels).
pub(super) fn rough_circles(
    edges: &[Edge],
    dims: (usize, usize),
    scale: f64,
    (min_r, max_r): (f64, f64),
) -> Vec<(Circle, f64)> {
    let mut out = Vec::new();
    for (cx, cy, r_bin, cell) in vote(edges, dims, (min_r, max_r), parallel::parts()) {
        for r in radii(edges, cx, cy, r_bin / RADIUS_RATIO, r_bin * RADIUS_RATIO) {
            let rough = Circle { cx, cy, r }.enlarged(scale);
            out.push((rough, (1.5 + 0.5 * cell) / scale));
        }
    }
    out
}

/// An edge point: position and unit gradient direction.
#[derive(Clone, Copy, Debug)]
pub(super) struct Edge {
    x: f64,
    y: f64,
    ux: f64,
    uy: f64,
}

/// Sobel gradients thinned to ridges along their direction, above a threshold set by the
/// image's own gradient statistics.
pub(super) fn edge_points(image: ArrayView2<f64>) -> Vec<Edge> {
    let (h, w) = image.dim();
    if h < 3 || w < 3 {
        return Vec::new();
    }
    // The gradient is computed again where an edge is kept rather than stored for every
    // pixel: two planes fewer of the working copy's size.
    let gradient = |y: usize, x: usize| {
        let p = |dy: usize, dx: usize| image[[y + dy - 1, x + dx - 1]];
        (
            (p(0, 2) + 2.0 * p(1, 2) + p(2, 2)) - (p(0, 0) + 2.0 * p(1, 0) + p(2, 0)),
            (p(2, 0) + 2.0 * p(2, 1) + p(2, 2)) - (p(0, 0) + 2.0 * p(0, 1) + p(0, 2)),
        )
    };
    let inner = |y: usize, x: usize| (1..h - 1).contains(&y) && (1..w - 1).contains(&x);
    // Row bands, one per core for a large copy, put together in row order.
    let parts = parallel::parts_for(h * w);
    let mut magnitude = vec![0.0; h * w];
    parallel::fill_rows_in_parts(parts, &mut magnitude, w, |rows, band| {
        for (y, row) in rows.zip(band.chunks_mut(w)) {
            for (x, m) in row.iter_mut().enumerate() {
                if inner(y, x) {
                    let (gx, gy) = gradient(y, x);
                    *m = length(gx, gy);
                }
            }
        }
    });
    let positive: Vec<f64> = magnitude.iter().copied().filter(|&m| m > 0.0).collect();
    if positive.is_empty() {
        return Vec::new();
    }
    let threshold = 0.15 * quantile(positive, 0.98);
    let ridge = |y: usize, edges: &mut Vec<Edge>| {
        if !(1..h - 1).contains(&y) {
            return;
        }
        let at = |y: usize, x: usize| magnitude[y * w + x];
        for x in 1..w - 1 {
            let m = at(y, x);
            if m <= threshold {
                continue;
            }
            let (gx, gy) = gradient(y, x);
            let (ux, uy) = (gx / m, gy / m);
            // Neighbours along the gradient: keep local maxima only.
            let (sx, sy) = (ux.round() as isize, uy.round() as isize);
            let along =
                |dx: isize, dy: isize| at((y as isize + dy) as usize, (x as isize + dx) as usize);
            if m < along(sx, sy) || m < along(-sx, -sy) {
                continue;
            }
            edges.push(Edge {
                x: x as f64,
                y: y as f64,
                ux,
                uy,
            });
        }
    };
    parallel::rows_in_parts(h, parts, |rows, edges| rows.for_each(|y| ridge(y, edges)))
}

/// Consecutive radius bins of the vote differ by this factor.
const RADIUS_RATIO: f64 = 1.08;
/// Vote cells are at least this many working pixels across ...
const CELL: f64 = 2.0;
/// ... and this share of the bin's radius: a ball drawn a few percent elongated (a lens
/// off-axis, a crop rescaled unevenly) spreads its centre's votes over a few percent of r.
const CELL_SHARE: f64 = 0.015;
/// Gradient directions are told apart in this many sectors.
const SECTORS: f64 = 16.0;

/// One cell of a vote map in 32 bits, so that a map of 320 × 320 cells stays in a core's
/// cache: the votes (low half, saturating) and the sectors they came from (high half).
#[derive(Clone, Copy, Default)]
struct VoteCell(u32);

impl VoteCell {
    fn votes(self) -> f64 {
        f64::from(self.0 & 0xffff)
    }

    fn directions(self) -> u16 {
        (self.0 >> 16) as u16
    }

    fn add(&mut self, sector: u16) {
        let count = u32::from(self.0 & 0xffff != 0xffff);
        self.0 = (self.0 + count) | 1 << (16 + sector);
    }
}

/// The cells of one radius bin's vote map: their size (working pixels) and how many there
/// are across and down.
#[derive(Clone, Copy)]
struct Grid {
    cell: f64,
    cw: usize,
    ch: usize,
}

impl Grid {
    fn new(cell: f64, (h, w): (usize, usize)) -> Self {
        Grid {
            cell,
            cw: (w as f64 / cell).ceil() as usize,
            ch: (h as f64 / cell).ceil() as usize,
        }
    }

    /// Whether (x, y) (in cells) lies on the map.
    fn holds(self, x: f64, y: f64) -> bool {
        x >= 0.0 && y >= 0.0 && x < self.cw as f64 && y < self.ch as f64
    }
}

/// One radius bin's vote map: its grid and its cells.
struct VoteMap {
    grid: Grid,
    cells: Vec<VoteCell>,
}

impl VoteMap {
    fn new(grid: Grid) -> Self {
        VoteMap {
            grid,
            cells: vec![VoteCell::default(); grid.ch * grid.cw],
        }
    }

    /// A vote at (x, y) (in cells) from `sector`; false when outside the map.
    fn add(&mut self, x: f64, y: f64, sector: u16) -> bool {
        if !self.grid.holds(x, y) {
            return false;
        }
        // SAFETY: x and y are not NaN and lie in [0, width) and [0, height), which a u32
        // holds: their integer parts are representable (this skips the saturating casts'
        // checks in the vote's innermost loop).
        let (x, y) = unsafe { (x.to_int_unchecked::<u32>(), y.to_int_unchecked::<u32>()) };
        self.cells[y as usize * self.grid.cw + x as usize].add(sector);
        true
    }

    /// The sectors seen in the cell (x, y) and its neighbours.
    fn seen_around(&self, x: usize, y: usize) -> u16 {
        let Grid { cw, ch, .. } = self.grid;
        let mut around = 0u16;
        for yy in y.saturating_sub(1)..(y + 2).min(ch) {
            for xx in x.saturating_sub(1)..(x + 2).min(cw) {
                around |= self.cells[yy * cw + xx].directions();
            }
        }
        around
    }
}

/// The centre radius of vote bin `bin`.
fn bin_radius(min_r: f64, bin: usize) -> f64 {
    min_r * RADIUS_RATIO.powf(bin as f64 + 0.5)
}

/// Every edge point votes, at every radius between `min_r` and `max_r`, for the centre
/// that far along its gradient line, on both sides, in a map per radius bin; each cell
/// also records from which directions its votes came. A texture's straight edges spread
/// their votes over every bin and come from few directions; a circle's gather in one bin
/// and come from all around. Returns the [`CANDIDATES`] best peaks as (x, y, radius, cell),
/// scored by votes per unit of circumference times the share of directions seen.
fn vote(
    edges: &[Edge],
    (h, w): (usize, usize),
    (min_r, max_r): (f64, f64),
    parts: usize,
) -> Vec<(f64, f64, f64, f64)> {
    let (radii, lines) = (bin_radii(min_r, max_r), lines_of(edges));
    // Each part walks the bins in order and votes in the next bin no part has taken yet (a part
    // that falls behind takes fewer), so the bins' peaks come tagged with their bin.
    let taken: Vec<AtomicBool> = radii.iter().map(|_| AtomicBool::new(false)).collect();
    let mut by_bin: Vec<(usize, Vec<Peak>)> = in_parts(parts, |_, _| {
        vote_bins(&lines, &radii, min_r, (h, w), |bin| {
            !taken[bin].swap(true, Ordering::Relaxed)
        })
    })
    .into_iter()
    .flatten()
    .collect();
    by_bin.sort_by_key(|&(bin, _)| bin);
    let mut found: Vec<Peak> = by_bin.into_iter().flat_map(|(_, peaks)| peaks).collect();
    found.sort_by(|a, b| b.0.total_cmp(&a.0));
    found.truncate(CANDIDATES);
    found
        .into_iter()
        .map(|(_, x, y, r, cell)| (x, y, r, cell))
        .collect()
}

/// The radii one working pixel apart from `min_r` to `max_r`, per bin.
fn bin_radii(min_r: f64, max_r: f64) -> Vec<Vec<f64>> {
    let bins = ((max_r / min_r).ln() / RADIUS_RATIO.ln()).ceil() as usize + 1;
    let mut radii: Vec<Vec<f64>> = vec![Vec::new(); bins];
    for r in (0..).map(|k| min_r + k as f64).take_while(|&r| r <= max_r) {
        let bin = (((r / min_r).ln() / RADIUS_RATIO.ln()) as usize).min(bins - 1);
        radii[bin].push(r);
    }
    radii
}

/// Each edge point's line, on each side.
fn lines_of(edges: &[Edge]) -> Vec<Line> {
    edges
        .iter()
        .flat_map(|e| {
            [-1.0, 1.0].map(|side: f64| {
                // The direction from the centre to the edge point.
                let angle = (-side * e.uy).atan2(-side * e.ux) + std::f64::consts::PI;
                let sector =
                    ((angle / std::f64::consts::TAU * SECTORS) as u16).min(SECTORS as u16 - 1);
                (e.x, e.y, side * e.ux, side * e.uy, sector)
            })
        })
        .collect()
}

/// An edge point's line on one side: its point, its unit step towards the centre and the
/// sector of the direction from the centre to it.
type Line = (f64, f64, f64, f64, u16);
/// A vote map's peak: (score, x, y, radius, cell size).
type Peak = (f64, f64, f64, f64, f64);

/// The peaks of the bins `mine` picks, each with its bin. A line stops voting at its first vote
/// outside the picture, as it would in one walk through every bin: in a bin it does not vote
/// in, a line leaves the map iff its last radius's vote would. (A line starts inside the
/// picture and its votes move monotonically away along a straight line, so the votes on a
/// convex map are an unbroken run from the first.) One map at a time per part, so that the map
/// being filled stays in the cache.
fn vote_bins(
    lines: &[Line],
    radii: &[Vec<f64>],
    min_r: f64,
    dims: (usize, usize),
    mine: impl Fn(usize) -> bool,
) -> Vec<(usize, Vec<Peak>)> {
    let mut inside = vec![true; lines.len()];
    let mut found = Vec::new();
    for (bin, radii) in radii.iter().enumerate() {
        let r = bin_radius(min_r, bin);
        let grid = Grid::new((CELL_SHARE * r).max(CELL), dims);
        if !mine(bin) {
            follow(lines, radii, grid, &mut inside);
            continue;
        }
        let mut map = VoteMap::new(grid);
        cast(&mut map, lines, radii, &mut inside);
        let peaks = bin_peaks(&map, r, dims)
            .into_iter()
            .map(|(score, x, y)| (score, x, y, r, grid.cell))
            .collect();
        found.push((bin, peaks));
    }
    found
}

/// The votes of the lines still `inside` at `radii`, into `map`; a line whose vote falls
/// outside it stops there and is no longer inside.
fn cast(map: &mut VoteMap, lines: &[Line], radii: &[f64], inside: &mut [bool]) {
    let k = 1.0 / map.grid.cell;
    for (&(x, y, ux, uy, sector), inside) in lines.iter().zip(inside.iter_mut()) {
        if !*inside {
            continue;
        }
        // In the map's cells.
        let (x0, y0, dx, dy) = (x * k, y * k, ux * k, uy * k);
        *inside = radii
            .iter()
            .all(|&r| map.add(x0 + r * dx, y0 + r * dy, sector));
    }
}

/// Which lines [`cast`] would leave inside after `radii` on `grid`, without casting a vote:
/// those whose vote at the last radius falls on the map.
fn follow(lines: &[Line], radii: &[f64], grid: Grid, inside: &mut [bool]) {
    let Some(&r) = radii.last() else {
        return;
    };
    let k = 1.0 / grid.cell;
    for (&(x, y, ux, uy, _), inside) in lines.iter().zip(inside.iter_mut()) {
        let (x0, y0, dx, dy) = (x * k, y * k, ux * k, uy * k);
        *inside = *inside && grid.holds(x0 + r * dx, y0 + r * dy);
    }
}

/// The best peaks of one bin's vote map (radius `r`) as (score, x, y): votes per unit of
/// circumference (and of cell size) times the square of the share of directions seen, on
/// the part of the circle inside the picture.
fn bin_peaks(map: &VoteMap, r: f64, (h, w): (usize, usize)) -> Vec<(f64, f64, f64)> {
    let Grid { cell, cw, ch } = map.grid;
    let grid = Array2::from_shape_fn((ch, cw), |(y, x)| map.cells[y * cw + x].votes());
    let smooth = crate::image::blur::gaussian_blur(grid.view(), 1.0);
    // A circle's centre cell gathers about one vote per edge point per pixel of cell.
    let circumference = std::f64::consts::TAU * r * cell / CELL;
    let mut found = Vec::new();
    for (y, x) in peaks(&smooth, CANDIDATES, (0.5 * r / cell).max(2.0)) {
        let (y, x) = (y as usize, x as usize);
        let around = map.seen_around(x, y);
        let centre = |c: usize| (c as f64 + 0.5) * cell - 0.5;
        let (cx, cy) = (centre(x), centre(y));
        let visible = visible_sectors(cx, cy, r, (h, w));
        if visible.count_ones() < SECTORS as u32 / 2 {
            continue;
        }
        let inside = (f64::from(visible.count_ones()) / SECTORS).max(UNCUT);
        let share = f64::from((around & visible).count_ones()) / (inside * SECTORS);
        found.push((
            smooth[[y, x]] / (circumference * inside) * share * share,
            cx,
            cy,
        ));
    }
    found
}

/// The direction sectors (as [`vote`] numbers them) in which the circle's rim lies inside a
/// `w × h` picture.
fn visible_sectors(cx: f64, cy: f64, r: f64, (h, w): (usize, usize)) -> u16 {
    (0..SECTORS as u16)
        .filter(|&sector| {
            let theta =
                (f64::from(sector) + 0.5) / SECTORS * std::f64::consts::TAU - std::f64::consts::PI;
            let (x, y) = (cx + r * theta.cos(), cy + r * theta.sin());
            x >= 0.0 && y >= 0.0 && x <= w as f64 - 1.0 && y <= h as f64 - 1.0
        })
        .fold(0, |mask, sector| mask | 1 << sector)
}

/// The `n` strongest local maxima of a vote map, at least `spacing` apart, as (y, x).
fn peaks(acc: &Array2<f64>, n: usize, spacing: f64) -> Vec<(f64, f64)> {
    let (h, w) = acc.dim();
    let acc = acc.as_standard_layout();
    let Some(cells) = acc.as_slice() else {
        return Vec::new();
    };
    let mut maxima: Vec<(f64, usize, usize)> = Vec::new();
    for y in 1..h.saturating_sub(1) {
        let (above, row, below) = (
            &cells[(y - 1) * w..y * w],
            &cells[y * w..(y + 1) * w],
            &cells[(y + 1) * w..(y + 2) * w],
        );
        for x in 1..w - 1 {
            let v = row[x];
            if v > 0.0
                && row[x - 1] <= v
                && row[x + 1] <= v
                && above[x - 1..=x + 1].iter().all(|&n| n <= v)
                && below[x - 1..=x + 1].iter().all(|&n| n <= v)
            {
                maxima.push((v, y, x));
            }
        }
    }
    maxima.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut chosen: Vec<(f64, f64)> = Vec::new();
    for (_, y, x) in maxima {
        let (y, x) = (y as f64, x as f64);
        if chosen
            .iter()
            .all(|&(cy, cx)| (cy - y).hypot(cx - x) >= spacing)
        {
            chosen.push((y, x));
            if chosen.len() == n {
                break;
            }
        }
    }
    chosen
}

/// Per whole radius from 0 to `max_r`, how many of 90 sectors around (cx, cy) have an edge
/// point within a pixel of it pointing at the centre.
pub(super) fn rim_coverage(
    edges: &[Edge],
    cx: f64,
    cy: f64,
    min_r: f64,
    max_r: f64,
) -> impl Fn(usize) -> u32 {
    let bins = max_r.ceil() as usize + 2;
    let mut sectors = vec![0u128; bins];
    for e in edges {
        let (dx, dy) = (e.x - cx, e.y - cy);
        let d = length(dx, dy);
        if d < min_r - 1.0 || d > max_r + 1.0 {
            continue;
        }
        let alignment = (dx * e.ux + dy * e.uy).abs() / d;
        if alignment < 0.92 {
            continue;
        }
        let sector = (((dy.atan2(dx) + std::f64::consts::PI) / std::f64::consts::TAU * 90.0)
            as usize)
            .min(89);
        sectors[d.round() as usize] |= 1u128 << sector;
    }
    move |r: usize| {
        let at = |r: usize| sectors.get(r).copied().unwrap_or(0);
        (at(r.saturating_sub(1)) | at(r) | at(r + 1)).count_ones()
    }
}

/// The radii around (cx, cy) at which the largest fractions of the circumference have an
/// edge point pointing at the centre: the best [`RADII_PER_CENTRE`] local maxima.
fn radii(edges: &[Edge], cx: f64, cy: f64, min_r: f64, max_r: f64) -> Vec<f64> {
    let coverage = rim_coverage(edges, cx, cy, min_r, max_r);
    let profile: Vec<(u32, usize)> = (min_r.ceil() as usize..=max_r.floor() as usize)
        .map(|r| (coverage(r), r))
        .collect();
    let mut maxima: Vec<(u32, usize)> = profile
        .iter()
        .enumerate()
        .filter(|&(i, &(c, _))| {
            c >= 12
                && profile[i.saturating_sub(1)].0 <= c
                && profile.get(i + 1).is_none_or(|next| next.0 <= c)
        })
        .map(|(_, &p)| p)
        .collect();
    maxima.sort_by(|a, b| b.cmp(a));
    let mut chosen: Vec<f64> = Vec::new();
    for (_, r) in maxima {
        let r = r as f64;
        if chosen.iter().all(|&c| (c - r).abs() > 0.05 * c + 1.0) {
            chosen.push(r);
            if chosen.len() == RADII_PER_CENTRE {
                break;
            }
        }
    }
    chosen
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A bright disc cut by the picture's right edge, a smaller one inside, and a bar: lines
    /// that leave the picture at every radius bin.
    fn scene() -> Array2<f64> {
        Array2::from_shape_fn((150, 200), |(y, x)| {
            let (x, y) = (x as f64, y as f64);
            let big = (x - 170.0).hypot(y - 80.0) < 50.0;
            let small = (x - 60.0).hypot(y - 50.0) < 20.0;
            let bar = (20.0..110.0).contains(&x) && (115.0..125.0).contains(&y);
            if big || small || bar { 0.9 } else { 0.1 }
        })
    }

    #[test]
    fn the_vote_split_between_threads_is_the_vote_of_one_to_the_bit() {
        let image = crate::image::blur::gaussian_blur(scene().view(), 1.0);
        let edges = edge_points(image.view());
        let dims = image.dim();
        let one = vote(&edges, dims, (6.0, 120.0), 1);
        assert!(!one.is_empty(), "the scene's circles are voted for");
        let bits = |found: &[(f64, f64, f64, f64)]| -> Vec<[u64; 4]> {
            found
                .iter()
                .map(|&(x, y, r, cell)| [x, y, r, cell].map(f64::to_bits))
                .collect()
        };
        for parts in 2..=3 {
            let split = vote(&edges, dims, (6.0, 120.0), parts);
            assert_eq!(bits(&split), bits(&one), "{parts} parts");
        }
    }

    #[test]
    fn following_a_bin_leaves_inside_the_lines_its_votes_would() {
        // Lines grazing the right edge of a 301 px wide picture leave it at every radius; the
        // maps' cells overhang the edge by different amounts, so a line that left one map may
        // fall on a later one, where only the walk's memory keeps it from voting.
        let dims = (1000, 301);
        let lines: Vec<Line> = (0..400)
            .map(|k| {
                let ux = f64::from(k) * 0.0001;
                (299.0, 10.0, ux, (1.0 - ux * ux).sqrt(), (k % 16) as u16)
            })
            .collect();
        let radii = bin_radii(6.0, 300.0);
        let (mut cast_inside, mut followed) = (vec![true; lines.len()], vec![true; lines.len()]);
        let mut back_on_a_later_map = 0;
        for (bin, radii) in radii.iter().enumerate() {
            let r = bin_radius(6.0, bin);
            let grid = Grid::new((CELL_SHARE * r).max(CELL), dims);
            let before = cast_inside.clone();
            cast(&mut VoteMap::new(grid), &lines, radii, &mut cast_inside);
            follow(&lines, radii, grid, &mut followed);
            assert_eq!(followed, cast_inside, "bin {bin}");
            let mut fresh = vec![true; lines.len()];
            cast(&mut VoteMap::new(grid), &lines, radii, &mut fresh);
            back_on_a_later_map += (0..lines.len())
                .filter(|&l| !before[l] && !radii.is_empty() && fresh[l])
                .count();
        }
        assert!(cast_inside.iter().any(|&i| !i) && cast_inside.iter().any(|&i| i));
        assert!(back_on_a_later_map > 0, "no line fell on a later map");
    }
}
