//! Sample directions on the sphere and the random numbers behind them.
//!
//! The generator is 32-bit only (PCG with a 32-bit state and the RXS-M-XS output), so WGSL,
//! which has no 64-bit integers, can reproduce it bit for bit with wrapping `u32` arithmetic.
//! Floats are formed from the top 24 bits, which every f32 represents exactly.

use glam::{DMat3, DVec3, Vec3};
use serde::{Deserialize, Serialize};

/// PCG-RXS-M-XS-32: a 32-bit linear congruential state with a permuted output.
#[derive(Clone, Debug)]
pub struct Pcg32 {
    state: u32,
}

const PCG_MULTIPLIER: u32 = 747_796_405;
const PCG_INCREMENT: u32 = 2_891_336_453;

/// The output permutation of one state (also a good 32-bit integer hash).
pub fn pcg_hash(input: u32) -> u32 {
    let state = input
        .wrapping_mul(PCG_MULTIPLIER)
        .wrapping_add(PCG_INCREMENT);
    let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277_803_737);
    (word >> 22) ^ word
}

impl Pcg32 {
    /// A stream determined by a 64-bit seed (both halves matter).
    pub fn new(seed: u64) -> Self {
        let low = seed as u32;
        let high = (seed >> 32) as u32;
        Pcg32 {
            state: pcg_hash(low ^ pcg_hash(high)),
        }
    }

    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(PCG_MULTIPLIER).wrapping_add(PCG_INCREMENT);
        let word = ((old >> ((old >> 28) + 4)) ^ old).wrapping_mul(277_803_737);
        (word >> 22) ^ word
    }

    /// Uniform in [0, 1), a multiple of 2^-24.
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
    }
}

/// The largest sample count the baker accepts (1024 x 1024 strata).
pub const MAX_SAMPLES: u32 = 1 << 20;

/// The square number nearest to `requested` (at least 1): stratified sampling needs a
/// sqrt(N) x sqrt(N) grid.
pub fn nearest_square(requested: u32) -> u32 {
    let side = (requested as f64).sqrt().round().max(1.0) as u32;
    side * side
}

/// How the bake draws its sample directions and turns them into transfer (`--sampling`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum Sampling {
    /// Plain Monte Carlo: independent uniform directions on the sphere, shared by all vertices.
    Uniform,
    /// The tutorial's jittered sqrt(N) x sqrt(N) grid on the sphere, shared by all vertices.
    Stratified,
    /// A spherical Fibonacci set turned by a random rotation, shared by all vertices.
    Fibonacci,
    /// A randomly shifted Fibonacci lattice with cosine-weighted density on each vertex's own
    /// hemisphere: no ray goes below the horizon, and the density carries the cosine.
    Cosine,
    /// The Fibonacci set with a control variate: the unoccluded transfer in closed form, minus
    /// a Monte Carlo estimate of the part that geometry blocks.
    ControlVariate,
}

impl Sampling {
    pub fn name(self) -> &'static str {
        match self {
            Sampling::Uniform => "uniform",
            Sampling::Stratified => "stratified",
            Sampling::Fibonacci => "fibonacci",
            Sampling::Cosine => "cosine",
            Sampling::ControlVariate => "control-variate",
        }
    }

    pub const ALL: [Sampling; 5] = [
        Sampling::Uniform,
        Sampling::Stratified,
        Sampling::Fibonacci,
        Sampling::Cosine,
        Sampling::ControlVariate,
    ];

    /// The sample count used for `requested`: the stratified grid needs a square number.
    pub fn samples_used(self, requested: u32) -> u32 {
        match self {
            Sampling::Stratified => nearest_square(requested),
            _ => requested.max(1),
        }
    }

    /// The direction set of a bake; `count` must come from [`Sampling::samples_used`].
    pub fn directions(self, count: u32, seed: u64) -> SampleSet {
        match self {
            Sampling::Uniform => uniform_sphere(count, seed),
            Sampling::Stratified => stratified_sphere(count, seed),
            Sampling::Fibonacci | Sampling::ControlVariate => fibonacci_sphere(count, seed),
            Sampling::Cosine => cosine_hemisphere(count, seed),
        }
    }

    /// How the projected sums become transfer.
    pub fn estimator(self) -> Estimator {
        match self {
            Sampling::ControlVariate => Estimator::Blocked,
            _ => Estimator::Visible,
        }
    }
}

/// What the projected sums run over, for `t_k = (1/pi) integral V(w) max(0, n.w) y_k(w) dw`.
/// The density is the sample set's (see [`SampleSet::weight`] and [`DirectionFrame`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Estimator {
    /// `(w/pi) sum over visible s of f(s)`, with `f(s) = (n.w_s) y_k(w_s)` for uniform
    /// densities and `y_k(w_s)` when the density carries the cosine.
    Visible,
    /// `t_k(unoccluded, closed form) - (w/pi) sum over blocked s of f(s)`: only the blocked
    /// part is estimated, so the error shrinks with the occluded fraction.
    Blocked,
}

impl Estimator {
    /// Whether the sums run over blocked rays rather than visible ones.
    pub fn sums_blocked(self) -> bool {
        self == Estimator::Blocked
    }
}

/// Whether a set's directions are world directions or live in each vertex's tangent frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DirectionFrame {
    /// World directions, uniform density on the sphere.
    World,
    /// `(x, y, z)` means `x t + y b + z n` with `(t, b, n)` = [`tangent_frame`] of the normal;
    /// the density is `cos / pi` on the hemisphere, so sums leave the cosine out and run in
    /// the tangent frame, rotated to the world once per vertex.
    Tangent,
}

/// Directions shared by all vertices, with one quadrature weight each.
#[derive(Clone, Debug, PartialEq)]
pub struct SampleSet {
    pub directions: Vec<Vec3>,
    /// What each sample stands for: its solid angle (4 pi / N) for uniform densities, pi / N
    /// for the cosine density (so that `weight / pi` is the estimator's `1/N`).
    pub weight: f64,
    pub frame: DirectionFrame,
    /// Sample indices in runs of [`FAN_RUN`], each run a small cone ([`cone_runs`]).
    fans: Vec<u32>,
}

/// Samples a CPU fan packet casts together: one per lane (`packet::LANES`, held equal where the
/// two meet, in `bake::cpu`).
pub const FAN_RUN: usize = 16;

impl SampleSet {
    /// `directions` with one quadrature `weight` each, in `frame`; their fan runs are worked
    /// out here, once for every bake that casts the set.
    pub fn new(directions: Vec<Vec3>, weight: f64, frame: DirectionFrame) -> Self {
        let fans = cone_runs(&directions, FAN_RUN);
        SampleSet {
            directions,
            weight,
            frame,
            fans,
        }
    }

    /// The samples in runs of up to [`FAN_RUN`] indices, each run a small cone of directions:
    /// the CPU casts a tangent set one run at a time as a fan packet from each vertex, and the
    /// GPU's horizon pass lists samples in this order so that a SIMD group traces one cone.
    /// Every sample is in exactly one run; only the last run may be shorter.
    pub fn fan_runs(&self) -> std::slice::Chunks<'_, u32> {
        debug_assert_eq!(
            self.fans.len(),
            self.directions.len(),
            "runs of another set"
        );
        self.fans.chunks(FAN_RUN)
    }

    pub fn len(&self) -> usize {
        self.directions.len()
    }

    pub fn is_empty(&self) -> bool {
        self.directions.is_empty()
    }
}

/// Maps a point of the unit square to the sphere with uniform density:
/// `t = 2 acos(sqrt(1 - u))`, `p = 2 pi v`, so `cos t = 1 - 2u` is uniform.
pub fn square_to_sphere(u: f64, v: f64) -> DVec3 {
    let cos_theta = 1.0 - 2.0 * u;
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let phi = 2.0 * std::f64::consts::PI * v;
    DVec3::new(sin_theta * phi.cos(), sin_theta * phi.sin(), cos_theta)
}

/// Jittered stratified sampling of the sphere: one random point in each cell of a
/// `side x side` grid on the unit square, mapped by [`square_to_sphere`]. Sample
/// `i = a * side + b` lies in cell (a, b). `count` must be a square.
pub fn stratified_sphere(count: u32, seed: u64) -> SampleSet {
    let side = (count as f64).sqrt().round() as u32;
    assert_eq!(side * side, count, "stratified_sphere needs a square count");
    let mut rng = Pcg32::new(seed);
    let mut directions = Vec::with_capacity(count as usize);
    for a in 0..side {
        for b in 0..side {
            let u = (a as f64 + rng.next_f32() as f64) / side as f64;
            let v = (b as f64 + rng.next_f32() as f64) / side as f64;
            directions.push(square_to_sphere(u, v).normalize().as_vec3());
        }
    }
    SampleSet::new(
        directions,
        4.0 * std::f64::consts::PI / count as f64,
        DirectionFrame::World,
    )
}

/// Independent uniform directions on the sphere: plain Monte Carlo, the baseline.
pub fn uniform_sphere(count: u32, seed: u64) -> SampleSet {
    let mut rng = Pcg32::new(seed);
    let directions = (0..count)
        .map(|_| {
            let u = rng.next_f32() as f64;
            let v = rng.next_f32() as f64;
            square_to_sphere(u, v).normalize().as_vec3()
        })
        .collect();
    SampleSet::new(
        directions,
        4.0 * std::f64::consts::PI / count as f64,
        DirectionFrame::World,
    )
}

/// The golden angle's fraction of a turn, (3 - sqrt 5) / 2.
const GOLDEN_FRACTION: f64 = 0.381_966_011_250_105_1;

/// Spherical Fibonacci points (point i at height `1 - (2i + 1)/N`, turned by the golden angle
/// from the last), then all turned by one uniformly random rotation. The rotation makes every
/// point uniformly distributed on its own, so the estimate is unbiased; the lattice keeps the
/// points evenly spread, so its error falls faster than plain Monte Carlo's.
pub fn fibonacci_sphere(count: u32, seed: u64) -> SampleSet {
    let mut rng = Pcg32::new(seed);
    let rotation = random_rotation(&mut rng);
    let n = count as f64;
    let directions = (0..count)
        .map(|i| {
            let z = 1.0 - (2.0 * i as f64 + 1.0) / n;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = 2.0 * std::f64::consts::PI * (i as f64 * GOLDEN_FRACTION).fract();
            let point = DVec3::new(r * phi.cos(), r * phi.sin(), z);
            (rotation * point).normalize().as_vec3()
        })
        .collect();
    SampleSet::new(
        directions,
        4.0 * std::f64::consts::PI / n,
        DirectionFrame::World,
    )
}

/// A rotation drawn uniformly from SO(3): a uniform quaternion (Shoemake's method).
pub fn random_rotation(rng: &mut Pcg32) -> DMat3 {
    let u1 = rng.next_f32() as f64;
    let (u2, u3) = (
        2.0 * std::f64::consts::PI * rng.next_f32() as f64,
        2.0 * std::f64::consts::PI * rng.next_f32() as f64,
    );
    let (a, b) = ((1.0 - u1).sqrt(), u1.sqrt());
    let q = glam::DQuat::from_xyzw(a * u2.sin(), a * u2.cos(), b * u3.sin(), b * u3.cos());
    DMat3::from_quat(q.normalize())
}

/// A Fibonacci lattice on the unit square (point i at `((i + 1/2) / N, i * golden fraction)`),
/// shifted by one random offset modulo 1 (Cranley–Patterson rotation) and mapped to the upper
/// hemisphere with density `cos(theta) / pi` (Malley: a uniform point of the unit disk lifted
/// onto the hemisphere). The shift makes every point uniform on the square, so the estimate is
/// unbiased; the lattice keeps the points evenly spread. Directions are in the tangent frame,
/// z along the normal, stored in Morton order: consecutive lattice points are a golden angle
/// apart, while Morton-ordered samples next to each other are mostly close, which lavapipe's
/// walks gain from (docs/performance.md). The CPU casts the tighter cones of
/// [`SampleSet::fan_runs`] instead.
pub fn cosine_hemisphere(count: u32, seed: u64) -> SampleSet {
    let lattice = cosine_hemisphere_lattice_order(count, seed);
    // Ordered on the disk that Malley's lift starts from, where the points are uniform, so that
    // Morton cells of equal area hold equal numbers of samples.
    let on_disk: Vec<Vec3> = lattice
        .directions
        .iter()
        .map(|d| Vec3::new(d.x, d.y, 0.0))
        .collect();
    let directions = crate::morton::morton_order(&on_disk)
        .into_iter()
        .map(|i| lattice.directions[i as usize])
        .collect();
    SampleSet::new(directions, lattice.weight, lattice.frame)
}

/// The samples of [`cosine_hemisphere`] in the lattice's own order, which the Morton order
/// replaced; kept to measure what that order gains (`examples/sample_order.rs`).
pub fn cosine_hemisphere_lattice_order(count: u32, seed: u64) -> SampleSet {
    let mut rng = Pcg32::new(seed);
    let shift_u = rng.next_f32() as f64;
    let shift_v = rng.next_f32() as f64;
    let n = count as f64;
    let directions = (0..count)
        .map(|i| {
            let u = ((i as f64 + 0.5) / n + shift_u).fract();
            let v = (i as f64 * GOLDEN_FRACTION + shift_v).fract();
            square_to_cosine_hemisphere(u, v).normalize().as_vec3()
        })
        .collect();
    SampleSet::new(
        directions,
        std::f64::consts::PI / n,
        DirectionFrame::Tangent,
    )
}

/// The indices of `directions` in runs of `run`, each run a small cone: the set is halved
/// across the widest extent of its directions (as points on the unit sphere) until the parts
/// hold at most `run`, the first part of each halving a multiple of `run`, so that only the
/// last run can be short. The runs of the cosine set's Morton order, `run` consecutive
/// samples, are cells of a Z-curve on the disk that often join two distant patches; halving
/// keeps every run together, and a fan packet's walk of the dragon takes 11% fewer steps
/// (docs/performance.md).
fn cone_runs(directions: &[Vec3], run: usize) -> Vec<u32> {
    let mut order: Vec<u32> = (0..directions.len() as u32).collect();
    halve_into_cones(&mut order, directions, run.max(1));
    order
}

fn halve_into_cones(order: &mut [u32], directions: &[Vec3], run: usize) {
    if order.len() <= run {
        return;
    }
    let (low, high) = order
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(low, high), &i| {
            let d = directions[i as usize];
            (low.min(d), high.max(d))
        });
    let axis = (high - low).max_position();
    let first = run * order.len().div_ceil(2 * run);
    // Ties by index, so that the runs do not depend on the selection's internals.
    let key = |&i: &u32| (directions[i as usize][axis], i);
    order.select_nth_unstable_by(first, |a, b| {
        let (ka, kb) = (key(a), key(b));
        ka.0.total_cmp(&kb.0).then(ka.1.cmp(&kb.1))
    });
    let (first_part, rest) = order.split_at_mut(first);
    halve_into_cones(first_part, directions, run);
    halve_into_cones(rest, directions, run);
}

/// `r = sqrt(u)`, `phi = 2 pi v` on the disk, lifted to `z = sqrt(1 - u)`. The smallest u is
/// kept off 1 so that z stays positive.
pub fn square_to_cosine_hemisphere(u: f64, v: f64) -> DVec3 {
    let u = u.min(1.0 - 1e-7);
    let r = u.sqrt();
    let phi = 2.0 * std::f64::consts::PI * v;
    DVec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u).sqrt())
}

/// A right-handed orthonormal frame `(t, b, n)` around a unit normal, with no branch on the
/// normal's direction except its z sign (Duff et al., "Building an orthonormal basis,
/// revisited", 2017). wgsl/samples.wgsl's `tangent_frame` is its twin, in the same f32 steps.
pub fn tangent_frame(n: Vec3) -> [Vec3; 3] {
    let sign = if n.z >= 0.0 { 1.0f32 } else { -1.0 };
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    let tangent = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
    let bitangent = Vec3::new(b, sign + n.y * n.y * a, -n.y);
    [tangent, bitangent, n]
}

/// Each receiver's own turn of a tangent-frame set about its normal: neighbouring receivers
/// (a lightmap's texels) then cast different directions, so that their errors are independent
/// and a denoiser averages them out, where a set shared in one frame gives neighbours the same
/// error. A turn about the normal keeps the cosine density and each 16-sample cone of the Morton
/// order, and, the set's own azimuthal shift being uniform, keeps every estimate unbiased.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReceiverTurns {
    /// The bake's seed, mixed to 32 bits.
    pub seed: u32,
    /// The receiver number of the inputs' first receiver: a part of a bake keeps the turns
    /// its receivers have in the whole.
    pub first: u32,
}

impl ReceiverTurns {
    pub fn new(seed: u64) -> Self {
        let (low, high) = (seed as u32, (seed >> 32) as u32);
        ReceiverTurns {
            seed: pcg_hash(low ^ pcg_hash(high ^ TURN_STREAM)),
            first: 0,
        }
    }

    /// `(cos a, sin a)` of the turn of the inputs' receiver `receiver`.
    pub fn of(self, receiver: u32) -> [f32; 2] {
        receiver_turn(self.seed, self.first.wrapping_add(receiver))
    }

    /// The turns of the inputs' receivers from `offset` on.
    pub fn skipping(self, offset: u32) -> Self {
        ReceiverTurns {
            first: self.first.wrapping_add(offset),
            ..self
        }
    }
}

/// Keeps the turns' hash apart from the sample set's stream of the same seed.
const TURN_STREAM: u32 = 0x7475_726e;

/// `(cos a, sin a)` of receiver `receiver`'s turn: the rational parametrisation
/// `((1 - t^2) / (1 + t^2), 2t / (1 + t^2))` of `a = 2 atan t`, t uniform in [-1, 1) from the
/// hash's top 24 bits, and the half turn `a + pi` where its low bit is set. No trigonometry, so
/// WGSL (wgsl/samples.wgsl's `receiver_turn`) gives the same bits.
pub fn receiver_turn(seed: u32, receiver: u32) -> [f32; 2] {
    let bits = pcg_hash(receiver ^ seed);
    let t = (bits >> 8) as f32 * (2.0 / 16_777_216.0) - 1.0;
    let t2 = t * t;
    let (cos, sin) = ((1.0 - t2) / (1.0 + t2), (2.0 * t) / (1.0 + t2));
    if bits & 1 == 1 {
        [-cos, -sin]
    } else {
        [cos, sin]
    }
}

/// The frame `(t, b, n)` turned about `n` by `(cos a, sin a)`.
pub fn turned_frame([t, b, n]: [Vec3; 3], [cos, sin]: [f32; 2]) -> [Vec3; 3] {
    [t * cos + b * sin, b * cos - t * sin, n]
}

/// Maps a set's sample directions to world directions for one vertex: the identity for world
/// sets, the vertex's tangent frame (worked out once, not per sample) for tangent sets.
#[derive(Clone, Copy, Debug)]
pub struct VertexDirections {
    axes: Option<[Vec3; 3]>,
}

impl VertexDirections {
    pub fn new(frame: DirectionFrame, n: Vec3) -> Self {
        VertexDirections {
            axes: (frame == DirectionFrame::Tangent).then(|| tangent_frame(n)),
        }
    }

    /// [`VertexDirections::new`], a tangent frame turned by `turn` where there is one.
    pub fn turned(frame: DirectionFrame, n: Vec3, turn: Option<[f32; 2]>) -> Self {
        let plain = Self::new(frame, n);
        VertexDirections {
            axes: plain.axes.map(|axes| match turn {
                Some(turn) => turned_frame(axes, turn),
                None => axes,
            }),
        }
    }

    /// The tangent frame `(t, b, n)`, for tangent sets.
    pub fn axes(&self) -> Option<[Vec3; 3]> {
        self.axes
    }

    /// World direction of sample `d`.
    #[inline]
    pub fn world(&self, d: Vec3) -> Vec3 {
        match self.axes {
            None => d,
            Some([t, b, n]) => t * d.x + b * d.y + n * d.z,
        }
    }

    /// World directions of the samples `run` of `set` (a fan run), written to the front of
    /// `out`, which is returned cut to them.
    #[inline]
    pub fn world_run<'w>(&self, set: &SampleSet, run: &[u32], out: &'w mut [Vec3]) -> &'w [Vec3] {
        for (w, &s) in out.iter_mut().zip(run) {
            *w = self.world(set.directions[s as usize]);
        }
        &out[..run.len()]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn generator_is_deterministic_and_seed_dependent() {
        let a: Vec<u32> = (0..8)
            .scan(Pcg32::new(7), |r, _| Some(r.next_u32()))
            .collect();
        let b: Vec<u32> = (0..8)
            .scan(Pcg32::new(7), |r, _| Some(r.next_u32()))
            .collect();
        let c: Vec<u32> = (0..8)
            .scan(Pcg32::new(7 | (1 << 40)), |r, _| Some(r.next_u32()))
            .collect();
        assert_eq!(a, b);
        assert_ne!(a, c, "the high half of the seed must matter");
    }

    #[test]
    fn floats_are_uniform_in_the_unit_interval() {
        let mut rng = Pcg32::new(1);
        let n = 100_000;
        let mut histogram = [0u32; 10];
        for _ in 0..n {
            let x = rng.next_f32();
            assert!((0.0..1.0).contains(&x));
            histogram[(x * 10.0) as usize] += 1;
        }
        // Each bin holds 10,000 +- 95 (1 sigma); 5 sigma bounds.
        for count in histogram {
            assert!((count as i64 - 10_000).abs() < 475, "{histogram:?}");
        }
    }

    #[test]
    fn nearest_square_rounds_to_the_closest_grid() {
        assert_eq!(nearest_square(1024), 1024);
        assert_eq!(nearest_square(1000), 1024);
        assert_eq!(nearest_square(2), 1);
        assert_eq!(nearest_square(0), 1);
        assert_eq!(nearest_square(3), 4);
        assert_eq!(nearest_square(300), 289);
    }

    #[test]
    fn stratified_directions_are_unit_one_per_stratum() {
        let set = stratified_sphere(64 * 64, 3);
        assert_eq!(set.len(), 4096);
        let side = 64;
        for (i, d) in set.directions.iter().enumerate() {
            assert!((d.length() - 1.0).abs() < 1e-6);
            // Invert the map and check the point lies in its own cell.
            let u = (1.0 - d.z as f64) / 2.0;
            let mut v = (d.y as f64).atan2(d.x as f64) / (2.0 * std::f64::consts::PI);
            if v < 0.0 {
                v += 1.0;
            }
            let (a, b) = (i / side, i % side);
            let cell_u = u * side as f64;
            let cell_v = v * side as f64;
            assert!(cell_u > a as f64 - 1e-3 && cell_u < (a + 1) as f64 + 1e-3);
            // The azimuth wraps at v = 1.
            assert!(
                (cell_v > b as f64 - 1e-3 && cell_v < (b + 1) as f64 + 1e-3)
                    || (b == side - 1 && cell_v < 1e-3),
                "sample {i}: v cell {cell_v} not in {b}"
            );
        }
    }

    #[test]
    fn stratified_mean_direction_is_near_zero() {
        let set = stratified_sphere(32 * 32, 11);
        let mean: Vec3 = set.directions.iter().sum::<Vec3>() / set.len() as f32;
        // Stratification makes this far smaller than the 1/sqrt(N) of plain Monte Carlo.
        assert!(mean.length() < 0.01, "{mean}");
        assert!((set.weight * set.len() as f64 - 4.0 * std::f64::consts::PI).abs() < 1e-12);
    }

    #[test]
    fn receiver_turns_are_rotations_spread_over_the_whole_circle() {
        let turns = ReceiverTurns::new(3);
        assert_ne!(turns.seed, ReceiverTurns::new(4).seed);
        assert_eq!(turns.skipping(10).of(5), turns.of(15));
        let mut octants = [0u32; 8];
        for receiver in 0..80_000 {
            let [cos, sin] = turns.of(receiver);
            assert!((cos * cos + sin * sin - 1.0).abs() < 1e-6, "{cos}, {sin}");
            let angle = sin.atan2(cos).rem_euclid(std::f32::consts::TAU);
            octants[(angle / std::f32::consts::FRAC_PI_4) as usize % 8] += 1;
        }
        // a = 2 atan t, t uniform, has density (1 + t^2) / 4 over its half turn: from 0.79
        // to 1.57 times the even density, so no octant is far from an eighth.
        for count in octants {
            assert!((7_000..13_000).contains(&count), "{octants:?}");
        }
        // A turned frame is still right-handed and orthonormal, about the same normal.
        let n = Vec3::new(0.3, -0.5, 0.8).normalize();
        let [t, b, m] = turned_frame(tangent_frame(n), turns.of(7));
        assert_eq!(m, n);
        assert!(t.dot(b).abs() < 1e-6 && t.dot(n).abs() < 1e-6 && b.dot(n).abs() < 1e-6);
        assert!((t.cross(b) - n).length() < 1e-5);
    }

    #[test]
    fn tangent_frames_are_right_handed_and_orthonormal() {
        let mut rng = Pcg32::new(5);
        let mut normals: Vec<Vec3> = (0..1000)
            .map(|_| square_to_sphere(rng.next_f32() as f64, rng.next_f32() as f64).as_vec3())
            .collect();
        // The poles and the seam where the sign of z flips.
        normals.extend([Vec3::Z, Vec3::NEG_Z, Vec3::X, Vec3::new(0.6, 0.8, -0.0)]);
        for n in normals {
            let n = n.normalize();
            let [t, b, m] = tangent_frame(n);
            assert_eq!(m, n);
            for (u, v) in [(t, b), (b, n), (n, t)] {
                assert!(u.dot(v).abs() < 1e-6, "{n}: {u} . {v}");
            }
            for axis in [t, b] {
                assert!((axis.length() - 1.0).abs() < 1e-6);
            }
            assert!((t.cross(b) - n).length() < 1e-6, "{n}: not right-handed");
        }
    }

    #[test]
    fn fibonacci_points_are_evenly_spread_and_turn_with_the_seed() {
        let a = fibonacci_sphere(1000, 1);
        let b = fibonacci_sphere(1000, 2);
        assert_ne!(a.directions, b.directions);
        let mean: Vec3 = a.directions.iter().sum::<Vec3>() / 1000.0;
        assert!(mean.length() < 1e-3, "{mean}");
        // Evenly spread: the nearest neighbour of every point is about sqrt(4 pi / N) away,
        // never much closer (random points would have pairs a few times closer).
        let spacing = (4.0 * std::f32::consts::PI / 1000.0).sqrt();
        for (i, p) in a.directions.iter().enumerate() {
            let nearest = a
                .directions
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != i)
                .map(|(_, q)| (*p - *q).length())
                .fold(f32::MAX, f32::min);
            assert!(nearest > 0.5 * spacing, "point {i}: {nearest} vs {spacing}");
        }
    }

    #[test]
    fn cosine_directions_have_the_cosine_density() {
        let set = cosine_hemisphere(64 * 64, 9);
        assert_eq!(set.frame, DirectionFrame::Tangent);
        assert!(set.directions.iter().all(|d| d.z > 0.0));
        // Under density cos/pi: E[z] = 2/3, E[z^2] = 1/2, E[x] = E[y] = 0.
        let n = set.len() as f32;
        let mean: Vec3 = set.directions.iter().sum::<Vec3>() / n;
        let mean_z2 = set.directions.iter().map(|d| d.z * d.z).sum::<f32>() / n;
        assert!((mean.z - 2.0 / 3.0).abs() < 1e-3, "{mean}");
        assert!((mean_z2 - 0.5).abs() < 1e-3, "{mean_z2}");
        assert!(mean.x.abs() < 1e-3 && mean.y.abs() < 1e-3, "{mean}");
        assert!((set.weight * n as f64 - std::f64::consts::PI).abs() < 1e-9);
    }

    #[test]
    fn cosine_samples_in_morton_order_are_the_lattice_in_runs_of_small_cones() {
        let sorted = cosine_hemisphere(1024, 4);
        let lattice = cosine_hemisphere_lattice_order(1024, 4);
        let key = |d: &Vec3| d.to_array().map(f32::to_bits);
        let mut a: Vec<_> = sorted.directions.iter().map(key).collect();
        let mut b: Vec<_> = lattice.directions.iter().map(key).collect();
        a.sort_unstable();
        b.sort_unstable();
        assert_eq!(a, b, "not a permutation of the lattice");
        assert_eq!(sorted.weight, lattice.weight);
        // Widest angle between a run's first sample and the others, averaged over runs of 16.
        let spread = |set: &SampleSet| {
            let runs = set.directions.chunks(16);
            let count = runs.len() as f32;
            runs.map(|run| {
                run.iter()
                    .map(|d| run[0].dot(*d).clamp(-1.0, 1.0).acos())
                    .fold(0.0, f32::max)
            })
            .sum::<f32>()
                / count
        };
        let (sorted_spread, lattice_spread) = (spread(&sorted), spread(&lattice));
        assert!(
            sorted_spread < 0.5 * lattice_spread,
            "Morton runs span {sorted_spread} rad, lattice runs {lattice_spread} rad"
        );
    }

    #[test]
    fn fan_runs_cover_the_set_once_in_cones_tighter_than_morton_runs() {
        for count in [1, 15, 16, 17, 37, 1000, 1024] {
            let set = cosine_hemisphere(count, 6);
            let runs: Vec<&[u32]> = set.fan_runs().collect();
            let (last, full) = runs.split_last().unwrap();
            assert!(
                full.iter().all(|run| run.len() == FAN_RUN),
                "{count}: a short run"
            );
            assert!(!last.is_empty() && last.len() <= FAN_RUN);
            let mut all: Vec<u32> = runs.concat();
            all.sort_unstable();
            assert_eq!(
                all,
                (0..count).collect::<Vec<_>>(),
                "{count}: not a partition"
            );
        }
        // Mean angle of a run's directions from their mean direction.
        let spread = |set: &SampleSet, runs: Vec<Vec<u32>>| {
            let count = runs.len() as f32;
            runs.iter()
                .map(|run| {
                    let d = |&s: &u32| set.directions[s as usize];
                    let axis = run.iter().map(d).sum::<Vec3>().normalize();
                    run.iter()
                        .map(|s| axis.dot(d(s)).clamp(-1.0, 1.0).acos())
                        .sum::<f32>()
                        / run.len() as f32
                })
                .sum::<f32>()
                / count
        };
        let set = cosine_hemisphere(1024, 4);
        let morton: Vec<Vec<u32>> = (0..1024)
            .collect::<Vec<u32>>()
            .chunks(16)
            .map(<[u32]>::to_vec)
            .collect();
        let cones = set.fan_runs().map(<[u32]>::to_vec).collect();
        let (morton, cones) = (spread(&set, morton), spread(&set, cones));
        assert!(
            cones < 0.8 * morton,
            "runs {cones} rad from their axis, Morton runs {morton}"
        );
    }

    #[test]
    fn sample_counts_round_only_for_grids() {
        assert_eq!(Sampling::Stratified.samples_used(1000), 1024);
        assert_eq!(Sampling::Cosine.samples_used(1000), 1000);
        assert_eq!(Sampling::Fibonacci.samples_used(1000), 1000);
        assert_eq!(Sampling::Uniform.samples_used(1000), 1000);
        assert_eq!(Sampling::ControlVariate.samples_used(1000), 1000);
        for sampling in Sampling::ALL {
            let used = sampling.samples_used(300);
            assert_eq!(sampling.directions(used, 1).len(), used as usize);
        }
    }
}
