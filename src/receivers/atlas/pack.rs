//! Packing charts of any shape into an atlas of a given width, by their texels.
//!
//! Each chart's footprint is the range of texel rows it meets in each texel column (closed
//! squares, as `texels::rasterize` counts them, with a margin for the rounding of placed
//! corners). Charts go in largest first, in two stages:
//!
//! - Large charts stand on a skyline: per column, the lowest row a new chart may use there,
//!   [`GUTTER`] rows above the highest texel of any chart within [`GUTTER`] columns. Each takes,
//!   of both its turns (as laid out, and a quarter turn) and every column, the place that keeps
//!   its top lowest (then the leftmost, then the unturned).
//! - Small charts (both sides at most [`SMALL_CHART`] texels) first go, by their boxes, into the
//!   free texels the large ones left: below their overhangs and above their slopes. Only those
//!   that find no room stand on the skyline.
//!
//! Two charts' texels are then more than [`GUTTER`] texels apart (Chebyshev distance), so
//! `GUTTER` empty texels lie between them, as between a chart and the border.

use std::ops::Range;

use glam::DVec2;

use super::GUTTER;

/// A chart ready to pack: its triangles' corners in texels, inside `[0, size.x] x [0, size.y]`.
#[derive(Clone, Debug, PartialEq)]
pub struct TexelChart {
    pub corners: Vec<[DVec2; 3]>,
    pub size: DVec2,
}

/// Where a chart went: its lower-left corner's texel, and whether it was given a quarter turn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Placement {
    pub origin: [u32; 2],
    pub turned: bool,
}

/// Charts placed in an atlas at most `width` texels wide (gutters at both sides included),
/// and the width and height they take; `None` where a chart is wider than the atlas allows
/// either way round.
pub fn pack(charts: &[TexelChart], width: u32) -> Option<(Vec<Placement>, u32, u32)> {
    let mut order: Vec<usize> = (0..charts.len()).collect();
    let key = |c: &TexelChart| (c.size.x * c.size.y * 1024.0) as u64;
    // Stable: equal sizes keep chart order.
    order.sort_by_key(|&i| std::cmp::Reverse(key(&charts[i])));
    let (large, small): (Vec<usize>, Vec<usize>) =
        order.into_iter().partition(|&i| !is_small(&charts[i]));
    let mut packing = Packing {
        skyline: vec![GUTTER as i64; width as usize],
        placements: vec![
            Placement {
                origin: [0, 0],
                turned: false
            };
            charts.len()
        ],
        used_width: 0,
        height: 0,
    };
    let mut footprints = Vec::with_capacity(large.len());
    for &i in &large {
        let (x, y, turned, footprint) = on_skyline(&packing.skyline, &charts[i])?;
        packing.place(i, x, y, turned, &footprint);
        footprints.push(footprint);
    }
    // Small charts first go into the holes the large ones left below the skyline.
    let mut holes = Holes::new(width as usize, packing.height.max(0) as usize);
    for (&i, footprint) in large.iter().zip(&footprints) {
        let [x, y] = packing.placements[i].origin;
        holes.block(footprint, x as i64, y as i64);
    }
    for &i in &small {
        let (x, y, turned, footprint) = match holes.find(&charts[i]) {
            Some(found) => found,
            None => on_skyline(&packing.skyline, &charts[i])?,
        };
        holes.block(&footprint, x, y);
        packing.place(i, x, y, turned, &footprint);
    }
    let least = 2 * GUTTER as i64 + 1;
    Some((
        packing.placements,
        packing.used_width.max(least) as u32,
        packing.height.max(least) as u32,
    ))
}

/// Charts placed so far: the skyline over them, where each went, and the width and height they
/// take with their gutters.
struct Packing {
    skyline: Vec<i64>,
    placements: Vec<Placement>,
    used_width: i64,
    height: i64,
}

impl Packing {
    fn place(&mut self, chart: usize, x: i64, y: i64, turned: bool, footprint: &Footprint) {
        footprint.raise(&mut self.skyline, x, y);
        self.height = self.height.max(y + footprint.top() + 1 + GUTTER as i64);
        self.used_width = self
            .used_width
            .max(x + footprint.columns.len() as i64 + GUTTER as i64);
        self.placements[chart] = Placement {
            origin: [x as u32, y as u32],
            turned,
        };
    }
}

/// The best place on the skyline for a chart, of both its turns: the one that keeps its top
/// lowest (then wastes least, then the leftmost, then the unturned): `(x, y, turned,
/// footprint)`; `None` where it is wider than the atlas either way round.
fn on_skyline(skyline: &[i64], chart: &TexelChart) -> Option<(i64, i64, bool, Footprint)> {
    let mut best: Option<(i64, i64, i64, bool, Footprint)> = None;
    for turned in [false, true] {
        let footprint = Footprint::of(&placed_corners(chart, turned));
        if let Some((x, y, waste)) = lowest_place(skyline, &footprint) {
            let top = y + footprint.top();
            if best
                .as_ref()
                .is_none_or(|b| (top, waste, x) < (b.0, b.1, b.2))
            {
                best = Some((top, waste, x, turned, footprint));
            }
        }
    }
    let (top, _, x, turned, footprint) = best?;
    Some((x, top - footprint.top(), turned, footprint))
}

/// Whether a chart is small enough to be packed into a hole by its box: both its sides at most
/// [`SMALL_CHART`] texels.
fn is_small(chart: &TexelChart) -> bool {
    chart.size.max_element() + 1.0 <= SMALL_CHART as f64
}

/// The longest side, in texels, of a chart packed into holes by its box. Most charts of a
/// scanned mesh are a few triangles at a few texels each; in the holes under the large charts'
/// overhangs they cost no atlas rows.
const SMALL_CHART: usize = 32;

/// The atlas' texels below the skyline, one bit each: set where a chart or its gutter lies
/// (the border's gutter too). Small charts are placed by their boxes, first fit in row order
/// from the lowest row; a box size's search resumes where the last search for it stopped,
/// since texels only ever get taken.
struct Holes {
    width: usize,
    height: usize,
    words_per_row: usize,
    taken: Vec<u64>,
    resume: std::collections::HashMap<(usize, usize), (usize, usize)>,
}

impl Holes {
    fn new(width: usize, height: usize) -> Holes {
        let words_per_row = width.div_ceil(64);
        let mut holes = Holes {
            width,
            height,
            words_per_row,
            taken: vec![0; words_per_row * height],
            resume: Default::default(),
        };
        let g = GUTTER as usize;
        for y in 0..height {
            let border = y < g || y + g >= height;
            if border {
                holes.take(y, 0, width);
            } else {
                holes.take(y, 0, g.min(width));
                holes.take(y, width.saturating_sub(g), width);
            }
        }
        holes
    }

    /// Takes texels `from..to` of row `y`.
    fn take(&mut self, y: usize, from: usize, to: usize) {
        let row = &mut self.taken[y * self.words_per_row..(y + 1) * self.words_per_row];
        for x in from..to {
            row[x / 64] |= 1 << (x % 64);
        }
    }

    /// Takes a chart's texels placed at `(x, y)` and its gutter around them.
    fn block(&mut self, footprint: &Footprint, x: i64, y: i64) {
        let g = GUTTER as i64;
        for (columns, low, high) in footprint.with_gutter(x, self.width) {
            let rows = (y + low - g).max(0)..(y + high + g + 1).min(self.height as i64);
            for row in rows {
                self.take(row as usize, columns.start, columns.end);
            }
        }
    }

    /// The last taken texel of row `y` in `x..x + n`, if any.
    fn last_taken(&self, y: usize, x: usize, n: usize) -> Option<usize> {
        let row = &self.taken[y * self.words_per_row..(y + 1) * self.words_per_row];
        (x..x + n).rev().find(|&c| row[c / 64] >> (c % 64) & 1 == 1)
    }

    /// The first free box of `columns` x `rows` texels, in row order from where the last search
    /// for that size stopped.
    fn first_free(&mut self, columns: usize, rows: usize) -> Option<(usize, usize)> {
        if columns > self.width || rows > self.height {
            return None;
        }
        let (mut y, mut x) = self.resume.get(&(columns, rows)).copied().unwrap_or((0, 0));
        let found = loop {
            if y + rows > self.height {
                break None;
            }
            if x + columns > self.width {
                (y, x) = (y + 1, 0);
                continue;
            }
            match (y..y + rows).find_map(|r| self.last_taken(r, x, columns)) {
                Some(taken) => x = taken + 1,
                None => break Some((x, y)),
            }
        };
        self.resume.insert((columns, rows), (y, x));
        found
    }

    /// A free place for a small chart's box, of both its turns, the lowest (then leftmost, then
    /// unturned): `(x, y, turned, footprint)`.
    fn find(&mut self, chart: &TexelChart) -> Option<(i64, i64, bool, Footprint)> {
        let mut best: Option<(usize, usize, bool, Footprint)> = None;
        for turned in [false, true] {
            let footprint = Footprint::of(&placed_corners(chart, turned));
            let box_rows = footprint.top() as usize + 1;
            if let Some((x, y)) = self.first_free(footprint.columns.len(), box_rows) {
                if best.as_ref().is_none_or(|b| (y, x) < (b.1, b.0)) {
                    best = Some((x, y, turned, footprint));
                }
            }
        }
        best.map(|(x, y, turned, footprint)| (x as i64, y as i64, turned, footprint))
    }
}

/// A chart's corners as placed at the origin: turned a quarter (counter-clockwise, then moved
/// back into the positive quadrant) when asked, and half a texel in, so that a corner on the
/// box sits on a texel centre and which texels it touches is unambiguous.
pub fn placed_corners(chart: &TexelChart, turned: bool) -> Vec<[DVec2; 3]> {
    let half = DVec2::splat(0.5);
    chart
        .corners
        .iter()
        .map(|c| {
            c.map(|p| {
                let p = if turned {
                    DVec2::new(chart.size.y - p.y, p.x)
                } else {
                    p
                };
                p + half
            })
        })
        .collect()
}

/// Per texel column of a chart (from column 0), the lowest and highest texel row it meets.
#[derive(Clone, Debug, PartialEq)]
struct Footprint {
    columns: Vec<(i64, i64)>,
}

impl Footprint {
    fn of(corners: &[[DVec2; 3]]) -> Footprint {
        // Placed corners are rounded to f32: a hundredth of a texel covers that at 16384.
        const MARGIN: f64 = 0.01;
        let mut columns: Vec<(i64, i64)> = Vec::new();
        for triangle in corners {
            let lo = triangle[0].min(triangle[1]).min(triangle[2]);
            let hi = triangle[0].max(triangle[1]).max(triangle[2]);
            let first = ((lo.x - MARGIN).ceil() as i64 - 1).max(0);
            let last = (hi.x + MARGIN).floor() as i64;
            if columns.len() <= last as usize {
                columns.resize(last as usize + 1, (i64::MAX, i64::MIN));
            }
            for x in first..=last {
                let (low, high) =
                    rows_in_slab(triangle, x as f64 - MARGIN, x as f64 + 1.0 + MARGIN);
                let rows = &mut columns[x as usize];
                rows.0 = rows.0.min(((low - MARGIN).ceil() as i64 - 1).max(0));
                rows.1 = rows.1.max((high + MARGIN).floor() as i64);
            }
        }
        Footprint { columns }
    }

    fn top(&self) -> i64 {
        self.columns.iter().map(|c| c.1).max().unwrap_or(0)
    }

    /// Raises the skyline over the chart placed at `(x, y)`.
    fn raise(&self, skyline: &mut [i64], x: i64, y: i64) {
        let g = GUTTER as i64;
        for (columns, _, high) in self.with_gutter(x, skyline.len()) {
            for s in &mut skyline[columns] {
                *s = (*s).max(y + high + g + 1);
            }
        }
    }

    /// For each texel column the chart meets, placed at column `x`: the atlas columns within
    /// [`GUTTER`] of it (within `0..width`), and the lowest and highest row it meets there.
    fn with_gutter(
        &self,
        x: i64,
        width: usize,
    ) -> impl Iterator<Item = (Range<usize>, i64, i64)> + '_ {
        let g = GUTTER as i64;
        let met = self.columns.iter().enumerate().filter(|(_, c)| c.0 <= c.1);
        met.map(move |(i, &(low, high))| {
            let column = x + i as i64;
            let from = (column - g).max(0) as usize;
            let to = ((column + g + 1) as usize).min(width);
            (from..to, low, high)
        })
    }
}

/// Where the chart stands on the skyline, its columns clear of the side gutters, leaving the
/// fewest texels unused beneath it (then lowest, then leftmost): `(x, y, texels unused)`.
fn lowest_place(skyline: &[i64], footprint: &Footprint) -> Option<(i64, i64, i64)> {
    let g = GUTTER as i64;
    let span = footprint.columns.len() as i64;
    let last_x = skyline.len() as i64 - g - span;
    let mut best: Option<(i64, i64, i64)> = None;
    for x in g..=last_x {
        let columns = || {
            footprint
                .columns
                .iter()
                .enumerate()
                .filter(|(_, c)| c.0 <= c.1)
                .map(move |(i, c)| (skyline[(x + i as i64) as usize], c.0))
        };
        let y = columns().map(|(s, low)| s - low).max().unwrap_or(g).max(0);
        let waste: i64 = columns().map(|(s, low)| y + low - s).sum();
        if best.is_none_or(|b| (y, waste) < (b.1, b.0)) {
            best = Some((waste, y, x));
        }
    }
    best.map(|(waste, y, x)| (x, y, waste))
}

/// The lowest and highest `y` of the triangle between the vertical lines `x = from` and
/// `x = to`: over its corners inside and where its edges cross the lines.
fn rows_in_slab(corners: &[DVec2; 3], from: f64, to: f64) -> (f64, f64) {
    let mut low = f64::INFINITY;
    let mut high = f64::NEG_INFINITY;
    let mut take = |y: f64| {
        low = low.min(y);
        high = high.max(y);
    };
    for i in 0..3 {
        let (a, b) = (corners[i], corners[(i + 1) % 3]);
        if a.x >= from && a.x <= to {
            take(a.y);
        }
        for line in [from, to] {
            if (a.x - line) * (b.x - line) < 0.0 {
                let t = (line - a.x) / (b.x - a.x);
                take(a.y + t * (b.y - a.y));
            }
        }
    }
    (low, high)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(side: f64) -> TexelChart {
        TexelChart {
            corners: vec![
                [DVec2::ZERO, DVec2::new(side, 0.0), DVec2::splat(side)],
                [DVec2::ZERO, DVec2::splat(side), DVec2::new(0.0, side)],
            ],
            size: DVec2::splat(side),
        }
    }

    #[test]
    fn a_footprint_is_the_texels_a_chart_meets() {
        // Placed half a texel in, a 3-texel square spans texels 0..=3 each way.
        let footprint = Footprint::of(&placed_corners(&square(3.0), false));
        assert_eq!(footprint.columns, vec![(0, 3); 4]);
        // A right triangle: column x meets rows up to its hypotenuse.
        let triangle = TexelChart {
            corners: vec![[DVec2::ZERO, DVec2::new(4.0, 0.0), DVec2::new(0.0, 4.0)]],
            size: DVec2::splat(4.0),
        };
        let footprint = Footprint::of(&placed_corners(&triangle, false));
        assert_eq!(
            footprint.columns,
            vec![(0, 4), (0, 4), (0, 3), (0, 2), (0, 1)]
        );
    }

    /// Asserts that every chart's texels lie inside the border's gutter and more than
    /// [`GUTTER`] texels from every other chart's.
    fn assert_gutters_kept(
        charts: &[TexelChart],
        placements: &[Placement],
        width: u32,
        height: u32,
    ) {
        let cells: Vec<Vec<(i64, i64)>> = charts
            .iter()
            .zip(placements)
            .map(|(c, p)| {
                let f = Footprint::of(&placed_corners(c, p.turned));
                let mut cells = Vec::new();
                for (i, &(lo, hi)) in f.columns.iter().enumerate() {
                    for y in lo..=hi {
                        cells.push((p.origin[0] as i64 + i as i64, p.origin[1] as i64 + y));
                    }
                }
                cells
            })
            .collect();
        let g = GUTTER as i64;
        for &(x, y) in cells.iter().flatten() {
            assert!(x >= g && y >= g && x < width as i64 - g && y < height as i64 - g);
        }
        for (i, a) in cells.iter().enumerate() {
            for b in &cells[i + 1..] {
                for p in a {
                    for q in b {
                        assert!((p.0 - q.0).abs().max((p.1 - q.1).abs()) > g, "{p:?} {q:?}");
                    }
                }
            }
        }
    }

    #[test]
    fn small_charts_fill_the_room_the_large_ones_leave() {
        let triangle = TexelChart {
            corners: vec![[DVec2::ZERO, DVec2::new(40.0, 0.0), DVec2::new(0.0, 40.0)]],
            size: DVec2::splat(40.0),
        };
        let (_, _, alone) = pack(std::slice::from_ref(&triangle), 48).unwrap();
        // Twenty small squares fit above the triangle's slope: the atlas grows no taller.
        let mut charts = vec![triangle];
        charts.extend((0..20).map(|_| square(3.0)));
        assert!(is_small(&charts[1]) && !is_small(&charts[0]));
        let (placements, width, height) = pack(&charts, 48).unwrap();
        assert_eq!(height, alone);
        assert_gutters_kept(&charts, &placements, width, height);
        // Where the room runs out, the rest stand on the skyline, gutters kept.
        charts.extend((0..40).map(|_| square(3.0)));
        let (placements, width, height) = pack(&charts, 48).unwrap();
        assert!(height > alone);
        assert_gutters_kept(&charts, &placements, width, height);
    }

    #[test]
    fn charts_interlock_and_keep_the_gutter() {
        // Two right triangles pack into little more than one square's rows.
        let triangle = TexelChart {
            corners: vec![[DVec2::ZERO, DVec2::new(20.0, 0.0), DVec2::new(0.0, 20.0)]],
            size: DVec2::splat(20.0),
        };
        let charts = vec![triangle.clone(), triangle];
        let (placements, width, height) = pack(&charts, 60).unwrap();
        assert!(height < 2 * 21, "height {height}");
        assert_gutters_kept(&charts, &placements, width, height);
    }

    #[test]
    fn a_chart_wider_than_the_atlas_is_turned_or_refused() {
        let long = TexelChart {
            corners: vec![[DVec2::ZERO, DVec2::new(30.0, 0.0), DVec2::new(0.0, 4.0)]],
            size: DVec2::new(30.0, 4.0),
        };
        let (placements, _, height) = pack(std::slice::from_ref(&long), 12).unwrap();
        assert!(placements[0].turned && height >= 30);
        assert!(pack(&[long], 5).is_none());
    }
}
