//! Seams: surface edges that lie in the atlas twice, once on each of two charts (or at two
//! places of one chart, where a UV set is cut). Bilinear lookups on the two sides read
//! different texels, baked at different points, and disagree: the light steps along the seam.
//! Only edges between faces within 30 degrees of each other are seams to stitch: across a
//! sharper crease each face blocks the directions below its own plane, and the light steps.
//!
//! [`seam_rows`] asks that lookups on the two sides agree at points along every seam edge
//! (lightmappers' seam stitching), and [`solve`] finds the texel values, least squares:
//! minimise `sum_t anchor_t |x_t - x0_t|^2 + sum_rows weight |lookup_a(x) - lookup_b(x)|^2`,
//! the same weights for every coefficient. The normal equations are symmetric positive
//! definite and solved by Jacobi-preconditioned conjugate gradients, one solve per
//! coefficient, a few coefficients side by side and a few such groups in parallel.

use std::collections::HashMap;
use std::ops::Range;

use glam::DVec2;
use rayon::prelude::*;

use super::atlas::Atlas;
use super::texels::bilinear_taps;
use crate::scene::Scene;

/// The cosine of the widest angle between two faces whose shared edge is stitched (30
/// degrees): across a sharper crease each face blocks the directions below its own plane, and
/// the light legitimately steps.
const SMOOTH_COSINE: f32 = 0.866;

/// How much agreement across a seam weighs against a texel keeping its baked value.
pub const SEAM_WEIGHT: f64 = 10.0;

/// Lookups per texel of a seam edge's length (on its longer side), so that every texel along
/// the seam is constrained.
const POINTS_PER_TEXEL: f64 = 2.0;

/// The residual, relative to the right-hand side, at which the solve stops.
const TOLERANCE: f64 = 1e-3;

/// Conjugate-gradient steps at most.
const MAX_STEPS: usize = 200;

/// One seam edge: its two ends in the atlas on one side (`a`) and the other (`b`), in texel
/// units, the ends paired by the surface point they stand for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Seam {
    pub a: [DVec2; 2],
    pub b: [DVec2; 2],
}

impl Seam {
    /// The points of the seam looked up on each side: `(a, b)` pairs at the same surface points.
    pub fn points(&self) -> Vec<(DVec2, DVec2)> {
        let length = self.a[0]
            .distance(self.a[1])
            .max(self.b[0].distance(self.b[1]));
        let count = (length * POINTS_PER_TEXEL).ceil().max(1.0) as usize + 1;
        (0..count)
            .map(|k| {
                let t = k as f64 / (count - 1) as f64;
                (self.a[0].lerp(self.a[1], t), self.b[0].lerp(self.b[1], t))
            })
            .collect()
    }
}

/// The seams of `scene` in `atlas`: edges shared by exactly two triangles, through the same two
/// vertices, whose corners at the edge lie at different places in the atlas. An edge whose
/// sides hold different copies of a vertex (a crease: split normals; an albedo border) is no
/// seam: the light may step there.
pub fn seams(scene: &Scene, atlas: &Atlas) -> Vec<Seam> {
    // Per edge (its vertices, lower first), each triangle's corners at its two ends.
    let mut by_edge: HashMap<(u32, u32), Vec<Side>> = HashMap::new();
    for (t, corners) in scene.triangles.iter().enumerate() {
        let flat = atlas.corners[t].map(|c| c.as_dvec2());
        for i in 0..3 {
            let j = (i + 1) % 3;
            let (u, v) = (corners[i], corners[j]);
            if u == v {
                continue;
            }
            let ends = if u < v {
                (flat[i], flat[j])
            } else {
                (flat[j], flat[i])
            };
            by_edge
                .entry((u.min(v), u.max(v)))
                .or_default()
                .push((ends.0, ends.1, t as u32));
        }
    }
    // Apart by more than rounding: a thousandth of a texel.
    const APART: f64 = 1e-3;
    let normal = |t: u32| super::face_normal(&scene.positions, scene.triangles[t as usize]);
    let smooth = |a: u32, b: u32| {
        let (na, nb) = (normal(a), normal(b));
        na.dot(nb) >= SMOOTH_COSINE * na.length() * nb.length()
    };
    let mut seams: Vec<((u32, u32), Seam)> = by_edge
        .into_iter()
        .filter_map(|(edge, sides)| match sides.as_slice() {
            &[a, b]
                if (a.0.distance(b.0) > APART || a.1.distance(b.1) > APART) && smooth(a.2, b.2) =>
            {
                Some((
                    edge,
                    Seam {
                        a: [a.0, a.1],
                        b: [b.0, b.1],
                    },
                ))
            }
            _ => None,
        })
        .collect();
    // The map's order must not reach the stitching.
    seams.sort_unstable_by_key(|&(edge, _)| edge);
    seams.into_iter().map(|(_, seam)| seam).collect()
}

/// One side of an edge: its triangle's corners in the atlas at the edge's lower and higher
/// vertex, and the triangle.
type Side = (DVec2, DVec2, u32);

/// One equation on the texels, `sum_k w_k x[t_k] = 0` (side a's lookup less side b's), and its
/// weight in the sum of squares.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Row {
    taps: [(usize, f64); 8],
    weight: f64,
}

impl Row {
    /// The row's texels (row-major image indices) and their weights.
    pub fn taps(&self) -> &[(usize, f64); 8] {
        &self.taps
    }
}

/// Rows asking that lookups on the two sides of every seam agree, weighted [`SEAM_WEIGHT`].
pub fn seam_rows(width: u32, height: u32, seams: &[Seam]) -> Vec<Row> {
    let mut rows = Vec::new();
    for seam in seams {
        for (a, b) in seam.points() {
            let (ta, tb) = (
                bilinear_taps(width, height, a.as_vec2()),
                bilinear_taps(width, height, b.as_vec2()),
            );
            let mut taps = [(0, 0.0); 8];
            for k in 0..4 {
                taps[k] = (ta[k].0, ta[k].1 as f64);
                taps[k + 4] = (tb[k].0, -tb[k].1 as f64);
            }
            rows.push(Row {
                taps,
                weight: SEAM_WEIGHT,
            });
        }
    }
    rows
}

/// Solves for the texels `rows` read, in place in a `width` x `height` image of `stride`
/// values a texel (row-major; see the module's notes). `anchor` weighs, per texel, how firmly
/// it keeps its value (empty: 1 for all). Texels no row reads keep their values. `solved` is
/// told of every coefficient solved, [`solve_steps`] in all.
pub fn solve(
    (width, height): (u32, u32),
    (image, stride): (&mut [f32], usize),
    rows: &[Row],
    anchor: &[f32],
    solved: &mut dyn FnMut(u64),
) {
    SeamSystem::new(rows, anchor).solve((width, height), (image, stride), solved);
}

/// The stitching's system, built once for images that share their seams and anchors (a
/// lightmap stitched a group of coefficients at a time): [`Stitching::solve`] gives what
/// [`solve`] gives.
pub struct Stitching<'a>(SeamSystem<'a>);

impl<'a> Stitching<'a> {
    pub fn new(rows: &'a [Row], anchor: &[f32]) -> Self {
        Stitching(SeamSystem::new(rows, anchor))
    }

    /// [`solve`] with this system's rows and anchors.
    pub fn solve(&self, size: (u32, u32), image: (&mut [f32], usize), solved: &mut dyn FnMut(u64)) {
        self.0.solve(size, image, solved);
    }
}

impl SeamSystem<'_> {
    fn solve(
        &self,
        (width, height): (u32, u32),
        (image, stride): (&mut [f32], usize),
        solved: &mut dyn FnMut(u64),
    ) {
        let count = width as usize * height as usize;
        if self.rows.is_empty() || stride == 0 || image.len() != count * stride {
            return;
        }
        let solve = |image: &[f32], columns| self.solve_columns(image, stride, columns);
        solve_in_waves((image, stride), &self.texels, solve, solved);
    }
}

/// Solves every coefficient of `image` (`stride` values a texel) at `texels` with
/// `solve_columns` (the solution of a range of coefficients from the image as it stands,
/// texel-major) and writes it back.
///
/// The same matrix serves every coefficient: each solved on its own, up to [`COLUMNS`] side by
/// side (one pass over the matrix serves them all). Groups are solved in parallel, a wave of at
/// most [`GROUPS_IN_FLIGHT`] at a time, each wave written back before the next: what the solve
/// holds is a few groups' vectors, not every coefficient's solution. A column's arithmetic is
/// the same whatever columns stand beside it, so an image of few coefficients (a held
/// lightmap's group) is split into narrower groups, one a thread (a solve's vector steps run on
/// one thread), and gives the same bits. `solved` is told of every coefficient solved.
pub fn solve_in_waves(
    (image, stride): (&mut [f32], usize),
    texels: &[usize],
    solve_columns: impl Fn(&[f32], Range<usize>) -> Vec<f64> + Sync,
    solved: &mut dyn FnMut(u64),
) {
    let threads = rayon::current_num_threads().max(1);
    let width = stride.div_ceil(threads).clamp(1, COLUMNS);
    let groups: Vec<usize> = (0..stride).step_by(width).collect();
    let wave = threads.min(GROUPS_IN_FLIGHT);
    for firsts in groups.chunks(wave) {
        let image_now: &[f32] = image;
        let done: Vec<(Range<usize>, Vec<f64>)> = firsts
            .par_iter()
            .map(|&first| {
                let columns = first..stride.min(first + width);
                (columns.clone(), solve_columns(image_now, columns))
            })
            .collect();
        for (columns, x) in done {
            solved(columns.len() as u64);
            for (&t, values) in texels.iter().zip(x.chunks_exact(columns.len())) {
                for (at, &v) in image[t * stride..][columns.clone()].iter_mut().zip(values) {
                    *at = v as f32;
                }
            }
        }
    }
}

/// The steps [`solve`] reports for an image of `stride` values a texel: one a coefficient,
/// none where nothing is stitched.
pub fn solve_steps(stride: usize, rows: &[Row]) -> u64 {
    match rows.is_empty() {
        true => 0,
        false => stride as u64,
    }
}

/// Groups of [`COLUMNS`] coefficients solved at once, at most (each holds five vectors of
/// the seam texels' values).
pub const GROUPS_IN_FLIGHT: usize = 4;

/// The stitching's normal equations over the texels the rows read: each texel held to its
/// value with its anchor's weight, and each row's lookup difference pulled towards zero.
struct SeamSystem<'a> {
    rows: &'a [Row],
    /// Each row's taps, their texels numbered as in `texels`.
    local: Vec<[(usize, f64); 8]>,
    /// The texels the rows read (row-major image indices), in first-use order.
    texels: Vec<usize>,
    /// Each texel's anchor weight.
    weight: Vec<f64>,
    diagonal: Vec<f64>,
}

impl<'a> SeamSystem<'a> {
    fn new(rows: &'a [Row], anchor: &[f32]) -> Self {
        let mut index: HashMap<usize, usize> = HashMap::new();
        let mut texels = Vec::new();
        let mut number = |texel: usize| {
            *index.entry(texel).or_insert_with(|| {
                texels.push(texel);
                texels.len() - 1
            })
        };
        let local: Vec<[(usize, f64); 8]> = rows
            .iter()
            .map(|row| row.taps.map(|(texel, w)| (number(texel), w)))
            .collect();
        let weight: Vec<f64> = texels
            .iter()
            .map(|&t| anchor.get(t).map_or(1.0, |&a| a as f64))
            .collect();
        let mut diagonal = weight.clone();
        for (row, taps) in rows.iter().zip(&local) {
            for &(i, w) in taps {
                diagonal[i] += row.weight * w * w;
            }
        }
        SeamSystem {
            rows,
            local,
            texels,
            weight,
            diagonal,
        }
    }

    /// The solved values of coefficients `columns` of `image` (`stride` values a texel), from
    /// the values there, texel-major.
    fn solve_columns(&self, image: &[f32], stride: usize, columns: Range<usize>) -> Vec<f64> {
        let width = columns.len();
        let mut start = Vec::with_capacity(self.texels.len() * width);
        for &t in &self.texels {
            let values = &image[t * stride..][columns.clone()];
            start.extend(values.iter().map(|&v| v as f64));
        }
        let rhs: Vec<f64> = start
            .chunks_exact(width)
            .zip(&self.weight)
            .flat_map(|(v, w)| v.iter().map(move |v| v * w))
            .collect();
        conjugate_gradients(
            |x, out| self.apply(x, out, width),
            |r, z| self.precondition(r, z, width),
            (rhs, start),
            (width, TOLERANCE, MAX_STEPS),
        )
    }

    /// `out = A x`, `x` and `out` holding `columns` values a texel, texel-major.
    fn apply(&self, x: &[f64], out: &mut [f64], columns: usize) {
        for ((o, v), w) in out
            .chunks_exact_mut(columns)
            .zip(x.chunks_exact(columns))
            .zip(&self.weight)
        {
            for (o, v) in o.iter_mut().zip(v) {
                *o = w * v;
            }
        }
        let mut lookup = [0.0f64; COLUMNS];
        for (row, taps) in self.rows.iter().zip(&self.local) {
            let lookup = &mut lookup[..columns];
            // `Iterator::sum`'s start, as the single-coefficient solve summed.
            lookup.fill(-0.0);
            for &(i, w) in taps {
                for (l, v) in lookup.iter_mut().zip(&x[i * columns..(i + 1) * columns]) {
                    *l += w * v;
                }
            }
            for &(i, w) in taps {
                for (o, l) in out[i * columns..(i + 1) * columns].iter_mut().zip(&*lookup) {
                    *o += row.weight * w * l;
                }
            }
        }
    }

    /// `z = r / diagonal(A)`, texel by texel.
    fn precondition(&self, r: &[f64], z: &mut [f64], columns: usize) {
        for ((z, r), d) in z
            .chunks_exact_mut(columns)
            .zip(r.chunks_exact(columns))
            .zip(&self.diagonal)
        {
            for (z, r) in z.iter_mut().zip(r) {
                *z = r / d;
            }
        }
    }
}

/// Coefficients solved side by side by one `conjugate_gradients`.
pub const COLUMNS: usize = 4;

/// Solves `A x = b` for the symmetric positive definite `A` given as `apply`, preconditioned
/// by `precondition` (an approximate inverse), from `start`: `columns` systems at once, the
/// vectors texel-major. Each column is the solve it would be alone, with its own step
/// lengths, and stops when its own residual falls below `tolerance` times its right-hand
/// side, or after `max_steps`; the others go on.
pub(super) fn conjugate_gradients(
    apply: impl Fn(&[f64], &mut [f64]),
    precondition: impl Fn(&[f64], &mut [f64]),
    (b, start): (Vec<f64>, Vec<f64>),
    (columns, tolerance, max_steps): (usize, f64, usize),
) -> Vec<f64> {
    let n = b.len();
    // Per column, summed over the texels in order.
    let dots = |a: &[f64], b: &[f64]| {
        let mut sums = [-0.0f64; COLUMNS];
        for (a, b) in a.chunks_exact(columns).zip(b.chunks_exact(columns)) {
            for c in 0..columns {
                sums[c] += a[c] * b[c];
            }
        }
        sums
    };
    let floor = dots(&b, &b).map(|bb| tolerance * tolerance * bb.max(f64::MIN_POSITIVE));
    let mut x = start;
    let mut product = vec![0.0; n];
    apply(&x, &mut product);
    // The residual takes the right-hand side's place: one vector fewer held.
    let mut residual = b;
    for (r, p) in residual.iter_mut().zip(&product) {
        *r -= p;
    }
    let mut z = vec![0.0; n];
    precondition(&residual, &mut z);
    let mut direction = z.clone();
    let mut rz = dots(&residual, &z);
    let mut open = [false; COLUMNS];
    open[..columns].fill(true);
    for _ in 0..max_steps {
        let rr = dots(&residual, &residual);
        for c in 0..columns {
            open[c] &= rr[c] > floor[c];
        }
        if !open.contains(&true) {
            break;
        }
        apply(&direction, &mut product);
        let dp = dots(&direction, &product);
        let alpha: [f64; COLUMNS] = std::array::from_fn(|c| rz[c] / dp[c]);
        for (i, ((x, r), (d, p))) in x
            .iter_mut()
            .zip(residual.iter_mut())
            .zip(direction.iter().zip(&product))
            .enumerate()
        {
            let c = i % columns;
            if open[c] {
                *x += alpha[c] * d;
                *r -= alpha[c] * p;
            }
        }
        precondition(&residual, &mut z);
        let next = dots(&residual, &z);
        let beta: [f64; COLUMNS] = std::array::from_fn(|c| next[c] / rz[c]);
        for c in 0..columns {
            if open[c] {
                rz[c] = next[c];
            }
        }
        for (i, (d, z)) in direction.iter_mut().zip(&z).enumerate() {
            let c = i % columns;
            if open[c] {
                *d = z + beta[c] * *d;
            }
        }
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::receivers::atlas::generate_atlas;
    use crate::scene::{builtin, prepare::prepare};
    use glam::Vec3;

    #[test]
    fn seams_are_the_smooth_edges_between_charts() {
        let sphere = prepare(builtin::icosphere(Vec3::ZERO, 1.0, 3)).unwrap().0;
        let atlas = generate_atlas(&sphere, 20.0).unwrap();
        assert!(atlas.chart_count() > 1);
        let found = seams(&sphere, &atlas);
        assert_eq!(found.len(), sphere_edges_between_charts(&sphere, &atlas));
        // Each seam's two sides are one surface edge: about equal lengths in the atlas.
        for seam in &found {
            let (a, b) = (seam.a[0].distance(seam.a[1]), seam.b[0].distance(seam.b[1]));
            assert!((a / b - 1.0).abs() < 0.2, "{a} {b}");
        }
        let grid = builtin::grid_plane(Vec3::ZERO, Vec3::X, Vec3::Z, 4, Vec3::ONE);
        let grid = prepare(grid).unwrap().0;
        assert!(seams(&grid, &generate_atlas(&grid, 10.0).unwrap()).is_empty());
        // A box's six charts meet along creases of 90 degrees: no seams to stitch.
        let cube = prepare(builtin::closed_box(Vec3::ZERO, Vec3::ONE, 3))
            .unwrap()
            .0;
        let atlas = generate_atlas(&cube, 10.0).unwrap();
        assert_eq!(atlas.chart_count(), 6);
        assert!(seams(&cube, &atlas).is_empty());
    }

    fn sphere_edges_between_charts(scene: &Scene, atlas: &Atlas) -> usize {
        let mut owners: HashMap<(u32, u32), Vec<u32>> = HashMap::new();
        for (t, c) in scene.triangles.iter().enumerate() {
            for i in 0..3 {
                let (u, v) = (c[i], c[(i + 1) % 3]);
                owners
                    .entry((u.min(v), u.max(v)))
                    .or_default()
                    .push(atlas.chart_of[t]);
            }
        }
        owners
            .values()
            .filter(|c| c.len() == 2 && c[0] != c[1])
            .count()
    }

    /// RMS over the seams' points of the difference between the two sides' lookups.
    fn seam_difference(
        seams: &[Seam],
        width: u32,
        height: u32,
        image: &[f32],
        stride: usize,
    ) -> f64 {
        let rows = seam_rows(width, height, seams);
        let mut sum = 0.0;
        for row in &rows {
            for c in 0..stride {
                let d: f64 = row
                    .taps
                    .iter()
                    .map(|&(t, w)| w * image[t * stride + c] as f64)
                    .sum();
                sum += d * d;
            }
        }
        (sum / (rows.len() * stride) as f64).sqrt()
    }

    #[test]
    fn stitching_makes_the_sides_agree_and_leaves_other_texels() {
        let sphere = prepare(builtin::icosphere(Vec3::ZERO, 1.0, 2)).unwrap().0;
        let atlas = generate_atlas(&sphere, 12.0).unwrap();
        let found = seams(&sphere, &atlas);
        let (w, h) = (atlas.width, atlas.height);
        // Two coefficients a texel: each chart's own constant, and a ramp across the atlas.
        let texels = crate::receivers::texels::rasterize(&atlas);
        let mut image = vec![0.0f32; (w * h) as usize * 2];
        let mut valid = vec![false; (w * h) as usize];
        for (&(x, y), p) in texels.texels.iter().zip(&texels.points) {
            let at = (y * w + x) as usize;
            image[at * 2] = atlas.chart_of[p.triangle as usize] as f32;
            image[at * 2 + 1] = x as f32 * 0.1 - y as f32 * 0.05;
            valid[at] = true;
        }
        crate::receivers::texels::dilate(w, h, &mut image, 2, &mut valid, 4).unwrap();
        let before = seam_difference(&found, w, h, &image, 2);
        let baked = image.clone();
        let rows = seam_rows(w, h, &found);
        let mut reported = 0;
        solve((w, h), (&mut image, 2), &rows, &[], &mut |n| reported += n);
        assert_eq!(reported, solve_steps(2, &rows));
        assert_eq!(reported, 2);
        let after = seam_difference(&found, w, h, &image, 2);
        assert!(before > 0.5, "{before}");
        assert!(after < 0.1 * before, "{before} -> {after}");
        // Texels no lookup reads keep their values; deterministic.
        let read: std::collections::HashSet<usize> = seam_rows(w, h, &found)
            .iter()
            .flat_map(|row| row.taps.map(|(t, _)| t))
            .collect();
        for t in (0..(w * h) as usize).filter(|t| !read.contains(t)) {
            assert_eq!(image[2 * t..2 * t + 2], baked[2 * t..2 * t + 2]);
        }
        let mut again = baked.clone();
        solve((w, h), (&mut again, 2), &rows, &[], &mut |_| {});
        assert_eq!(again, image);
    }
}
