//! Least-squares texels (`--fit least-squares` with a lightmap): the map's values chosen so
//! that bilinear lookups best match the transfer baked at points spread evenly over every
//! chart, rather than each texel holding the transfer at its own centre (least-squares
//! lightmaps, as The Witness baked them).
//!
//! A texel at a chart's edge is read by lookups inside the chart but, point-sampled, holds the
//! transfer at the edge point nearest its centre; lookups between it and the texel inside
//! then bend the light within a texel of every chart edge. Fitted, it holds whatever makes the
//! lookups inside the chart right (the field carried on past the edge), and a texel inside
//! holds the best value for its whole footprint.
//!
//! minimise `sum_t ANCHOR anchor_t |x_t - x0_t|^2 + sum_p w |lookup_p(x) - T_p|^2
//! + sum_seams SEAM_WEIGHT |lookup_a(x) - lookup_b(x)|^2`, each coefficient on its own with
//! the same weights: `lookup_p` is the point's four bilinear taps, `w` a point's share of its
//! texel, `x0` the map as baked at the centres and filled, and the small anchor holds texels
//! no point decides. The normal equations need the points' values only through
//! `sum_p w taps_p T_p`, so [`PointSums`] adds each baked chunk in and lets it go.

use std::collections::HashMap;
use std::ops::Range;

use glam::{DVec2, Vec2};
use rayon::prelude::*;

use super::atlas::Atlas;
use super::seams::{self, Row};
use super::texels::bilinear_taps;
use super::SurfacePoint;

/// Fit points a texel's side: a `2 x 2` lattice in every texel's square, kept where it falls
/// inside a chart.
pub const POINTS_PER_SIDE: u32 = 2;

/// A point's weight: its share of a texel's area.
const POINT_WEIGHT: f64 = 1.0 / (POINTS_PER_SIDE * POINTS_PER_SIDE) as f64;

/// How firmly a texel keeps its value as baked at its centre and filled, against the
/// points' lookups: enough to decide texels that only a point's smallest tap reads.
pub const ANCHOR: f64 = 0.02;

/// How much agreement across a seam weighs (a point weighs a quarter). Without it each side
/// fits its own points' noise, and on a UV sphere the sides differ by more than that noise
/// (4.0% of the radiance against 2.8%); pulled as hard as the stitching pulls
/// (`seams::SEAM_WEIGHT`, 10), they bent the light on the teapot at 256²
/// (docs/performance.md).
pub const SEAM_WEIGHT: f64 = 1.0;

/// The residual, relative to the map's misfit as baked, at which each coefficient's solve
/// stops.
const TOLERANCE: f64 = 1e-2;

/// Conjugate-gradient steps at most.
const MAX_STEPS: usize = 400;

/// A fit point: where it lies on the surface and in the atlas (texel units).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FitPoint {
    pub surface: SurfacePoint,
    pub atlas: Vec2,
}

/// The fit points of `atlas`: the lattice of [`POINTS_PER_SIDE`]² points a texel, each kept
/// once, on the first triangle (in the scene's order) whose closed face in the atlas holds it.
/// Triangles flat in the atlas get none.
pub fn fit_points(atlas: &Atlas) -> Vec<FitPoint> {
    let n = POINTS_PER_SIDE as f64;
    let columns = (atlas.width * POINTS_PER_SIDE) as usize;
    let rows = (atlas.height * POINTS_PER_SIDE) as usize;
    let mut taken = vec![false; columns * rows];
    let mut points = Vec::new();
    for (t, corners) in atlas.corners.iter().enumerate() {
        let [a, b, c] = corners.map(|c| c.as_dvec2());
        let area2 = (b - a).perp_dot(c - a);
        if area2 == 0.0 || !area2.is_finite() {
            continue;
        }
        // Lattice point i stands at (i + 0.5) / n texels.
        let lo = a.min(b).min(c) * n - 0.5;
        let hi = a.max(b).max(c) * n - 0.5;
        for j in lattice_range(lo.y, hi.y, rows) {
            for i in lattice_range(lo.x, hi.x, columns) {
                let p = DVec2::new((i as f64 + 0.5) / n, (j as f64 + 0.5) / n);
                let weights = [
                    (c - b).perp_dot(p - b),
                    (a - c).perp_dot(p - c),
                    (b - a).perp_dot(p - a),
                ]
                .map(|x| x / area2);
                if weights.iter().any(|&x| x < 0.0) || taken[j * columns + i] {
                    continue;
                }
                taken[j * columns + i] = true;
                points.push(FitPoint {
                    surface: SurfacePoint {
                        triangle: t as u32,
                        barycentrics: weights.map(|x| x as f32),
                    },
                    atlas: p.as_vec2(),
                });
            }
        }
    }
    points
}

/// What a point's leak test found (`bake::texels::sites_in`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Site {
    /// Open to the scene.
    Open,
    /// Under a sheet of the scene lying nearer than the leak test's cover distance.
    Covered,
    /// Inside geometry.
    Inside,
}

/// A texel's points under a sheet are fitted where at least this many of its
/// [`POINTS_PER_SIDE`]² points lie under one: most of the texel is then the covered surface,
/// dark as a reference bake at those points is. Elsewhere they are left out, and the texel
/// stands for the open surface its bilinear lookups also serve. Measured at held-out points on
/// the dragon at 1024² over three seeds (docs/performance.md): with none fitted, the map's error
/// was 1.46 times below point-sampled vertices' (1.90 as seen); with these, 1.82 (1.95), and
/// 1.90 (2.17) once charts near geometry got denser (`atlas::density`). Taking texels by two
/// points reached 2.07 plain but 1.83 as seen; by fewer still (a crease's edge, a chart's rim),
/// it raised the teapot's error.
pub const COVERED_POINTS: u32 = 3;
const _: () = assert!(COVERED_POINTS <= POINTS_PER_SIDE * POINTS_PER_SIDE);

/// Which of `points` (on a `width` x `height` map) the fit leaves out, by the `sites` their
/// leak tests found: those inside geometry, and those under a sheet in a texel with fewer than
/// [`COVERED_POINTS`] such points.
fn left_out((width, height): (u32, u32), points: &[FitPoint], sites: &[Site]) -> Vec<bool> {
    let texel_of = |p: &FitPoint| {
        let column = (p.atlas.x.max(0.0) as usize).min(width as usize - 1);
        let row = (p.atlas.y.max(0.0) as usize).min(height as usize - 1);
        row * width as usize + column
    };
    let mut covered_in = HashMap::<usize, u32>::new();
    for (p, &site) in points.iter().zip(sites) {
        if site == Site::Covered {
            *covered_in.entry(texel_of(p)).or_default() += 1;
        }
    }
    points
        .iter()
        .zip(sites)
        .map(|(p, site)| match site {
            Site::Open => false,
            Site::Inside => true,
            Site::Covered => covered_in[&texel_of(p)] < COVERED_POINTS,
        })
        .collect()
}

/// The lattice indices from `lo` to `hi` (inclusive), within `0..size`.
fn lattice_range(lo: f64, hi: f64, size: usize) -> Range<usize> {
    let first = lo.ceil().max(0.0) as usize;
    let end = ((hi.floor() + 1.0).max(0.0) as usize).min(size);
    first..end.max(first)
}

/// What the fit needs of its points whatever the coefficient: which points it keeps, their
/// bilinear taps, and the texels those read.
pub struct PointTaps {
    size: (u32, u32),
    /// Per point, where its taps are in `taps` (`u32::MAX`: left out of the fit).
    kept: Vec<u32>,
    /// Each kept point's taps: texels numbered as in `texels`, bilinear weights.
    taps: Vec<[(u32, f32); 4]>,
    /// The texels the kept points read (row-major image indices), in first-use order.
    texels: Vec<usize>,
    /// Per texel of the map, its number in `texels` (`u32::MAX`: none).
    index: Vec<u32>,
}

impl PointTaps {
    /// The taps on a `width` x `height` map of `points`, less those the fit leaves out by the
    /// `sites` their leak tests found (`left_out`; one site a point, none given: all open).
    pub fn new((width, height): (u32, u32), points: &[FitPoint], sites: &[Site]) -> PointTaps {
        let skip = left_out((width, height), points, sites);
        let mut index = vec![u32::MAX; width as usize * height as usize];
        let (mut kept, mut taps, mut texels) = (Vec::new(), Vec::new(), Vec::new());
        for (p, point) in points.iter().enumerate() {
            if skip.get(p).copied().unwrap_or(false) {
                kept.push(u32::MAX);
                continue;
            }
            kept.push(taps.len() as u32);
            taps.push(
                bilinear_taps(width, height, point.atlas)
                    .map(|(t, w)| (local_index(&mut index, &mut texels, t), w)),
            );
        }
        PointTaps {
            size: (width, height),
            kept,
            taps,
            texels,
            index,
        }
    }

    /// Sums of the points' values (`stride` a texel read), none added yet.
    pub fn empty_sums(&self, stride: usize) -> Vec<f32> {
        vec![0.0; self.texels.len() * stride]
    }

    /// Adds `values` (`stride` a point) of the points from `first` on into `sums` (`stride` a
    /// texel read): `sum_p w tap_p(t) T_p`, each coefficient on its own, in the points' order.
    pub fn add(&self, sums: &mut [f32], stride: usize, first: usize, values: &[f32]) {
        for (values, &kept) in values.chunks_exact(stride).zip(&self.kept[first..]) {
            if kept == u32::MAX {
                continue;
            }
            for &(t, w) in &self.taps[kept as usize] {
                let w = (POINT_WEIGHT * w as f64) as f32;
                let sums = &mut sums[t as usize * stride..][..stride];
                for (s, v) in sums.iter_mut().zip(values) {
                    *s += w * v;
                }
            }
        }
    }

    /// The fit's normal equations: the points' taps, each texel held as firmly as `anchor`
    /// says (times [`ANCHOR`]), the lookups across `seams` pulled together.
    pub fn system(&self, anchor: &[f32], seams: &[Row]) -> TexelSystem {
        let size = self.size;
        let (mut texels, mut index) = (self.texels.clone(), self.index.clone());
        let seams: Vec<[(u32, f64); 8]> = seams
            .iter()
            .map(|row| {
                row.taps()
                    .map(|(t, w)| (local_index(&mut index, &mut texels, t), w))
            })
            .collect();
        let anchors = texels
            .iter()
            .map(|&t| ANCHOR * anchor.get(t).map_or(1.0, |&a| a as f64))
            .collect();
        let system = FitSystem::new(
            (&texels, &index, size.0 as usize),
            &self.taps,
            seams,
            anchors,
        );
        TexelSystem { texels, system }
    }
}

/// The fit's right-hand side gathered from the points' values as they are baked, and what
/// the solve needs of the points (their taps).
pub struct PointSums {
    taps: PointTaps,
    stride: usize,
    /// Per texel the points read, `sum_p w tap_p(t) T_p` for every coefficient.
    sums: Vec<f32>,
}

impl PointSums {
    /// Sums for a `width` x `height` map of `stride` values a texel, over `points` less those
    /// the fit leaves out by their `sites` (as [`PointTaps::new`]).
    pub fn new(size: (u32, u32), stride: usize, points: &[FitPoint], sites: &[Site]) -> PointSums {
        let taps = PointTaps::new(size, points, sites);
        let sums = taps.empty_sums(stride);
        PointSums { taps, stride, sums }
    }

    /// Adds the values (`stride` a point) of the points from `first` on.
    pub fn add(&mut self, first: usize, values: &[f32]) {
        self.taps.add(&mut self.sums, self.stride, first, values);
    }

    /// Fits `image` (the map as baked at the centres and filled, row-major, `stride` values a
    /// texel) to the points added, each texel held to its value as firmly as `anchor` says
    /// (times [`ANCHOR`]) and the lookups across `seams` pulled together. Texels that neither
    /// a point nor a seam reads keep their values. `solved` is told of every coefficient
    /// solved.
    pub fn fit(
        self,
        image: &mut [f32],
        anchor: &[f32],
        seams: &[Row],
        solved: &mut dyn FnMut(u64),
    ) {
        let system = self.taps.system(anchor, seams);
        drop(self.taps);
        system.solve((image, self.stride), &self.sums, solved);
    }
}

/// The fit's system over the texels the points and seams read, for any coefficients.
pub struct TexelSystem {
    /// The texels (row-major image indices): those the points read, then those only seams do.
    texels: Vec<usize>,
    system: FitSystem,
}

impl TexelSystem {
    /// Fits every coefficient of `image` (`stride` values a texel) to the points' `sums`
    /// ([`PointTaps::add`], `stride` a texel read), in waves of narrow solves
    /// ([`seams::solve_in_waves`]); `solved` is told of every coefficient solved. A
    /// coefficient's solve is the same arithmetic whatever coefficients stand beside it, so a
    /// map fitted a group of coefficients at a time gets the bits of one fitted whole.
    pub fn solve(
        &self,
        (image, stride): (&mut [f32], usize),
        sums: &[f32],
        solved: &mut dyn FnMut(u64),
    ) {
        let texels = &self.texels;
        let solve =
            |image: &[f32], columns| self.system.solve((image, stride), (texels, sums), columns);
        seams::solve_in_waves((image, stride), texels, solve, solved);
    }
}

/// `texel`'s number among `texels`, numbering it next if it has none (`index`, by row-major
/// index, holds the numbers given).
fn local_index(index: &mut [u32], texels: &mut Vec<usize>, texel: usize) -> u32 {
    if index[texel] == u32::MAX {
        index[texel] = texels.len() as u32;
        texels.push(texel);
    }
    index[texel]
}

/// The fit's normal equations over the texels the points and seams read. A point's taps
/// are a 2 x 2 block, so the points couple each texel only with the 3 x 3 texels around it:
/// their part of the matrix is a nine-entry stencil a texel, summed once, and each step's
/// product reads it texel by texel (in parallel; each texel's sum in a fixed order). The
/// seams couple texels anywhere and stay rows.
struct FitSystem {
    /// Per texel, its 3 x 3 neighbours' numbers (row by row; `u32::MAX` where none).
    neighbours: Vec<[u32; 9]>,
    /// Per texel, the points' weights with each neighbour (itself at the centre).
    stencil: Vec<[f64; 9]>,
    seams: Vec<[(u32, f64); 8]>,
    anchors: Vec<f64>,
    diagonal: Vec<f64>,
}

impl FitSystem {
    /// The system of `taps` and `seams` over `texels` (row-major indices in an image
    /// `width` wide, numbered by `index`), each texel held by its entry of `anchors`.
    fn new(
        (texels, index, width): (&[usize], &[u32], usize),
        taps: &[[(u32, f32); 4]],
        seams: Vec<[(u32, f64); 8]>,
        anchors: Vec<f64>,
    ) -> FitSystem {
        let n = texels.len();
        let height = index.len() / width.max(1);
        let neighbours: Vec<[u32; 9]> = texels
            .iter()
            .map(|&t| {
                let (x, y) = ((t % width) as i64, (t / width) as i64);
                std::array::from_fn(|k| {
                    let (nx, ny) = (x + k as i64 % 3 - 1, y + k as i64 / 3 - 1);
                    let inside =
                        (0..width as i64).contains(&nx) && (0..height as i64).contains(&ny);
                    match inside {
                        true => index[ny as usize * width + nx as usize],
                        false => u32::MAX,
                    }
                })
            })
            .collect();
        let mut stencil = vec![[0.0f64; 9]; n];
        let offset = |from: usize, to: usize| {
            let (a, b) = (texels[from], texels[to]);
            let dx = (b % width) as i64 - (a % width) as i64;
            let dy = (b / width) as i64 - (a / width) as i64;
            ((dy + 1) * 3 + dx + 1) as usize
        };
        for point in taps {
            for &(a, wa) in point {
                for &(b, wb) in point {
                    let k = offset(a as usize, b as usize);
                    stencil[a as usize][k] += POINT_WEIGHT * wa as f64 * wb as f64;
                }
            }
        }
        let mut diagonal: Vec<f64> = stencil
            .iter()
            .zip(&anchors)
            .map(|(s, a)| s[4] + a)
            .collect();
        for row in &seams {
            for &(i, w) in row {
                diagonal[i as usize] += SEAM_WEIGHT * w * w;
            }
        }
        // A texel read only by taps of weight zero (a point on its far edge) and held by no
        // anchor keeps its value.
        for d in &mut diagonal {
            if *d <= 0.0 {
                *d = 1.0;
            }
        }
        FitSystem {
            neighbours,
            stencil,
            seams,
            anchors,
            diagonal,
        }
    }

    /// The fitted values of coefficients `columns`, texel-major, from `image` (`stride` a
    /// texel) and the points' `sums` at `texels`.
    fn solve(
        &self,
        (image, stride): (&[f32], usize),
        (texels, sums): (&[usize], &[f32]),
        columns: Range<usize>,
    ) -> Vec<f64> {
        let width = columns.len();
        let mut start = Vec::with_capacity(texels.len() * width);
        let mut rhs = Vec::with_capacity(texels.len() * width);
        for (i, (&t, a)) in texels.iter().zip(&self.anchors).enumerate() {
            let values = &image[t * stride..][columns.clone()];
            start.extend(values.iter().map(|&v| v as f64));
            let point_sums = sums.get(i * stride..(i + 1) * stride);
            for (c, &v) in columns.clone().zip(values) {
                let summed = point_sums.map_or(0.0, |s| s[c] as f64);
                rhs.push(a * v as f64 + summed);
            }
        }
        // Solved for the change from the map as baked, so that the tolerance is relative to
        // the map's misfit rather than to the points' whole sums.
        let mut misfit = vec![0.0; rhs.len()];
        self.apply(&start, &mut misfit, width);
        for (m, b) in misfit.iter_mut().zip(&rhs) {
            *m = b - *m;
        }
        drop(rhs);
        let change = seams::conjugate_gradients(
            |x, out| self.apply(x, out, width),
            |r, z| {
                let pairs = z.chunks_exact_mut(width).zip(r.chunks_exact(width));
                for ((z, r), d) in pairs.zip(&self.diagonal) {
                    for (z, r) in z.iter_mut().zip(r) {
                        *z = r / d;
                    }
                }
            },
            (misfit, vec![0.0; start.len()]),
            (width, TOLERANCE, MAX_STEPS),
        );
        start.iter().zip(change).map(|(x, d)| x + d).collect()
    }

    /// `out = A x`, `x` and `out` holding `columns` values a texel, texel-major.
    fn apply(&self, x: &[f64], out: &mut [f64], columns: usize) {
        const TEXELS_A_TASK: usize = 4096;
        out.par_chunks_mut(columns * TEXELS_A_TASK)
            .enumerate()
            .for_each(|(task, out)| {
                let first = task * TEXELS_A_TASK;
                for (i, out) in out.chunks_exact_mut(columns).enumerate() {
                    let i = first + i;
                    let (stencil, neighbours) = (&self.stencil[i], &self.neighbours[i]);
                    for (c, o) in out.iter_mut().enumerate() {
                        let mut sum = self.anchors[i] * x[i * columns + c];
                        for (&w, &j) in stencil.iter().zip(neighbours) {
                            if j != u32::MAX {
                                sum += w * x[j as usize * columns + c];
                            }
                        }
                        *o = sum;
                    }
                }
            });
        let mut difference = [0.0f64; seams::COLUMNS];
        for row in &self.seams {
            let difference = &mut difference[..columns];
            difference.fill(0.0);
            for &(i, w) in row {
                let at = i as usize * columns;
                for (d, v) in difference.iter_mut().zip(&x[at..at + columns]) {
                    *d += w * v;
                }
            }
            for &(i, w) in row {
                let at = i as usize * columns;
                for (o, d) in out[at..at + columns].iter_mut().zip(&*difference) {
                    *o += SEAM_WEIGHT * w * d;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::receivers::atlas::generate_atlas;
    use crate::receivers::texels::{dilate, rasterize};
    use crate::scene::{builtin, prepare::prepare};
    use glam::Vec3;

    #[test]
    fn a_texels_covered_points_are_fitted_where_three_of_its_four_are_covered() {
        // Four points a texel (2 x 2 points), each texel's sites listed point by point.
        let texels: [[Site; 4]; 5] = {
            use Site::*;
            [
                [Covered, Covered, Covered, Open],   // mostly covered: fitted dark
                [Covered, Covered, Covered, Inside], // as well
                [Covered, Covered, Open, Open],      // half: the open surface's texel
                [Covered, Covered, Inside, Inside],  // two, whatever the others are
                [Inside, Open, Open, Open],          // nothing covered
            ]
        };
        let mut points = Vec::new();
        let mut sites = Vec::new();
        for (t, texel) in texels.iter().enumerate() {
            for (k, &site) in texel.iter().enumerate() {
                let offset = Vec2::new(0.25 + 0.5 * (k % 2) as f32, 0.25 + 0.5 * (k / 2) as f32);
                points.push(FitPoint {
                    surface: SurfacePoint {
                        triangle: 0,
                        barycentrics: [1.0, 0.0, 0.0],
                    },
                    atlas: Vec2::new(t as f32, 1.0) + offset,
                });
                sites.push(site);
            }
        }
        let skip = left_out((5, 2), &points, &sites);
        let expected: Vec<bool> = texels
            .iter()
            .enumerate()
            .flat_map(|(t, texel)| {
                texel.iter().map(move |&site| match site {
                    Site::Open => false,
                    Site::Inside => true,
                    Site::Covered => t >= 2,
                })
            })
            .collect();
        assert_eq!(skip, expected);
    }

    fn sphere_atlas() -> Atlas {
        let sphere = prepare(builtin::icosphere(Vec3::ZERO, 1.0, 3)).unwrap().0;
        generate_atlas(&sphere, 24.0).unwrap()
    }

    fn atlas_position(atlas: &Atlas, point: &SurfacePoint) -> DVec2 {
        let corners = atlas.corners[point.triangle as usize].map(|c| c.as_dvec2());
        let b = point.barycentrics.map(|b| b as f64);
        corners[0] * b[0] + corners[1] * b[1] + corners[2] * b[2]
    }

    #[test]
    fn fit_points_are_lattice_points_on_their_triangles_once_each() {
        let atlas = sphere_atlas();
        let points = fit_points(&atlas);
        let n = POINTS_PER_SIDE as f64;
        let mut seen = std::collections::HashSet::new();
        for point in &points {
            assert!(point.surface.barycentrics.iter().all(|&b| b >= 0.0));
            let at = atlas_position(&atlas, &point.surface);
            assert!(
                at.distance(point.atlas.as_dvec2()) < 1e-4,
                "{at} {}",
                point.atlas
            );
            let lattice = point.atlas.as_dvec2() * n - DVec2::splat(0.5);
            assert!(lattice.distance(lattice.round()) < 1e-9, "{lattice}");
            assert!(
                seen.insert((lattice.x as i64, lattice.y as i64)),
                "{lattice} twice"
            );
        }
        // As many points as the charts' area holds, up to what their edges round off.
        let area: f64 = atlas
            .corners
            .iter()
            .map(|c| {
                let [a, b, c] = c.map(|c| c.as_dvec2());
                0.5 * (b - a).perp_dot(c - a).abs()
            })
            .sum();
        let expected = area * n * n;
        let ratio = points.len() as f64 / expected;
        assert!(
            (0.97..1.03).contains(&ratio),
            "{} points for {expected:.0}",
            points.len()
        );
    }

    /// A field linear across the atlas, baked as the bake does at every covered texel (at the
    /// point of its triangle nearest its centre): lookups between a chart's edge texels and
    /// the texels inside read values clamped to the edge, and miss the field there; fitted,
    /// every lookup inside a chart finds it.
    #[test]
    fn a_linear_field_is_fitted_up_to_the_charts_edges() {
        let atlas = sphere_atlas();
        let (width, height) = (atlas.width, atlas.height);
        let field = |p: DVec2| [0.25 + 0.03 * p.x - 0.02 * p.y, 1.0 - 0.01 * p.x];
        let stride = 2;
        let texels = rasterize(&atlas);
        let mut image = vec![0.0f32; (width * height) as usize * stride];
        // As the bake holds them: texels baked at their centre firmly, the rest (baked at an
        // edge, or never) loosely.
        let mut anchor = vec![0.01f32; (width * height) as usize];
        for (&(x, y), point) in texels.texels.iter().zip(&texels.points) {
            let at = (y * width + x) as usize;
            let baked_at = atlas_position(&atlas, point);
            let value = field(baked_at);
            image[at * stride..][..stride].copy_from_slice(&value.map(|v| v as f32));
            if baked_at.distance(DVec2::new(x as f64 + 0.5, y as f64 + 0.5)) < 1e-6 {
                anchor[at] = 1.0;
            }
        }
        let mut valid = texels.valid_mask(&[]).unwrap();
        dilate(width, height, &mut image, stride, &mut valid, 4).unwrap();
        let points = fit_points(&atlas);
        let values: Vec<f32> = points
            .iter()
            .flat_map(|p| field(p.atlas.as_dvec2()).map(|v| v as f32))
            .collect();
        let worst = |image: &[f32]| {
            let mut worst = 0.0f64;
            for (point, truth) in points.iter().zip(values.chunks_exact(stride)) {
                for (c, &truth) in truth.iter().enumerate() {
                    let taps = bilinear_taps(width, height, point.atlas);
                    let lookup: f64 = taps
                        .iter()
                        .map(|&(t, w)| w as f64 * image[t * stride + c] as f64)
                        .sum();
                    worst = worst.max((lookup - truth as f64).abs());
                }
            }
            worst
        };
        let before = worst(&image);
        let mut sums = PointSums::new((width, height), stride, &points, &[]);
        let half = points.len() / 2 * stride;
        sums.add(0, &values[..half]);
        sums.add(half / stride, &values[half..]);
        sums.fit(&mut image, &anchor, &[], &mut |_| {});
        let after = worst(&image);
        // The field changes by 0.03 a texel: clamping at an edge misses by a good part of it.
        assert!(before > 0.01, "before the fit {before}");
        assert!(
            after < before / 4.0 && after < 0.004,
            "after the fit {after}, before {before}"
        );
    }

    #[test]
    fn skipped_points_are_left_out_and_unread_texels_keep_their_values() {
        let atlas = sphere_atlas();
        let (width, height) = (atlas.width, atlas.height);
        let points = fit_points(&atlas);
        let values = vec![1.0f32; points.len()];
        let fitted = |sites: &[Site]| {
            let mut image = vec![0.5f32; (width * height) as usize];
            let mut sums = PointSums::new((width, height), 1, &points, sites);
            sums.add(0, &values);
            sums.fit(&mut image, &[], &[], &mut |_| {});
            image
        };
        let all = fitted(&[]);
        let none = fitted(&vec![Site::Inside; points.len()]);
        assert!(none.iter().all(|&v| v == 0.5));
        // Far from every chart (the gutters and the empty atlas) texels keep their values;
        // texels under the points take theirs.
        let read: std::collections::HashSet<usize> = points
            .iter()
            .flat_map(|p| bilinear_taps(width, height, p.atlas).map(|(t, _)| t))
            .collect();
        for (t, &v) in all.iter().enumerate() {
            if !read.contains(&t) {
                assert_eq!(v, 0.5);
            }
        }
        let centre_texels = rasterize(&atlas);
        let inside = centre_texels
            .texels
            .iter()
            .zip(&centre_texels.points)
            .filter(|(&(x, y), p)| {
                atlas_position(&atlas, p).distance(DVec2::new(x as f64 + 0.5, y as f64 + 0.5))
                    < 1e-6
            })
            .map(|(&(x, y), _)| (y * width + x) as usize);
        // Each is held a little towards its value (0.5), and its neighbours past the chart's
        // edge more, so the points pull it most of the way to theirs (or past, to make up
        // for those neighbours).
        let inside: Vec<f32> = inside.map(|t| all[t]).collect();
        let mean = inside.iter().sum::<f32>() / inside.len() as f32;
        assert!((0.95..1.05).contains(&mean), "mean {mean}");
        assert!(inside.iter().all(|v| (0.85..1.2).contains(v)), "{inside:?}");
    }
}
