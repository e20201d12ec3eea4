//! The flattened arrays every backend reads — receivers, samples, SH table, BVH — built from
//! a prepared scene: what the GPU uploads and the CPU reference walks.

use super::*;

/// The flattened inputs every backend reads: the same arrays the GPU uploads.
pub struct DirectInputs<'a> {
    /// Ray origins, one per receiver: its position moved off the surface
    /// (`ray::offset_ray_origin`).
    pub origins: &'a [Vec3],
    /// The receivers' unit shading normals.
    pub normals: &'a [Vec3],
    /// The scene's triangles (what hit triangles' `source_index` refers to).
    pub triangles: &'a [[u32; 3]],
    /// The scene's vertex normals (for the shading normal at a hit); the same as `normals`
    /// when the receivers are the vertices.
    pub vertex_normals: &'a [Vec3],
    pub bvh: &'a Bvh,
    pub samples: &'a SampleSet,
    /// SH of each sample direction, `[sample][k]` (in the tangent frame for tangent sets).
    pub table: &'a ShTable,
    pub estimator: Estimator,
    /// Turns a tangent set's sums into the world, vertex by vertex (`table.bands` bands).
    pub tangent_to_world: &'a EulerShRotation,
    /// Each receiver's own turn of a tangent set about its normal, where receivers are to
    /// be denoised; `None`: every receiver casts the set in its plain tangent frame.
    pub turns: Option<ReceiverTurns>,
}

impl DirectInputs<'_> {
    /// How receiver `receiver` turns sample directions into world directions.
    pub fn directions_of(&self, receiver: usize) -> VertexDirections {
        let turn = self.turns.map(|turns| turns.of(receiver as u32));
        VertexDirections::turned(self.samples.frame, self.normals[receiver], turn)
    }

    /// The receivers `range`, each keeping its turn.
    pub fn part(&self, range: std::ops::Range<usize>) -> Self {
        DirectInputs {
            origins: &self.origins[range.clone()],
            normals: &self.normals[range.clone()],
            turns: self.turns.map(|turns| turns.skipping(range.start as u32)),
            ..*self
        }
    }
}

/// The arrays [`DirectInputs`] borrows, built from a prepared scene: what both backends read.
pub struct BakeInputs {
    pub origins: Vec<Vec3>,
    pub normals: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
    pub vertex_normals: Vec<Vec3>,
    pub bvh: Bvh,
    pub samples: SampleSet,
    pub table: ShTable,
    pub estimator: Estimator,
    pub tangent_to_world: EulerShRotation,
    pub turns: Option<ReceiverTurns>,
}

impl BakeInputs {
    /// Stratified sampling (the tutorial's); `scene` must be prepared (normals present) and
    /// `samples` a square.
    pub fn new(scene: &Scene, bands: u32, samples: u32, seed: u64) -> Self {
        Self::with_sampling(scene, bands, samples, seed, Sampling::Stratified)
    }

    /// What a bake of the vertices with `options` reads.
    pub fn for_options(scene: &Scene, options: &BakeOptions) -> Self {
        Self::for_receivers(scene, &Receivers::vertices(scene), options)
    }

    /// What a bake with `options` at `receivers` on `scene` reads.
    pub fn for_receivers(scene: &Scene, receivers: &Receivers, options: &BakeOptions) -> Self {
        let bvh = Bvh::build(&scene.positions, &scene.triangles);
        Self::with_tree(scene, receivers, bvh, options)
    }

    /// `samples` must come from [`Sampling::samples_used`].
    pub fn with_sampling(
        scene: &Scene,
        bands: u32,
        samples: u32,
        seed: u64,
        sampling: Sampling,
    ) -> Self {
        let receivers = Receivers::vertices(scene);
        Self::at_receivers(scene, &receivers, bands, samples, seed, sampling)
    }

    /// [`BakeInputs::for_receivers`] with the scene's tree already built.
    pub fn with_tree(
        scene: &Scene,
        receivers: &Receivers,
        bvh: Bvh,
        options: &BakeOptions,
    ) -> Self {
        let sampling = (
            options.bands,
            options.samples_used(),
            options.seed,
            options.sampling,
        );
        let mut inputs = Self::assemble(scene, receivers, bvh, sampling);
        inputs.turns = options.turns.then(|| ReceiverTurns::new(options.seed));
        inputs
    }

    fn at_receivers(
        scene: &Scene,
        receivers: &Receivers,
        bands: u32,
        samples: u32,
        seed: u64,
        sampling: Sampling,
    ) -> Self {
        let bvh = Bvh::build(&scene.positions, &scene.triangles);
        Self::assemble(scene, receivers, bvh, (bands, samples, seed, sampling))
    }

    fn assemble(
        scene: &Scene,
        receivers: &Receivers,
        bvh: Bvh,
        (bands, samples, seed, sampling): (u32, u32, u64, Sampling),
    ) -> Self {
        let vertex_normals = scene.normals.clone().expect("a prepared scene has normals");
        let origins = ray_origins(&receivers.ray_starts, &receivers.normals, bvh.extent());
        let samples = sampling.directions(samples, seed);
        let table = ShTable::new(bands, &samples.directions);
        BakeInputs {
            origins,
            normals: receivers.normals.clone(),
            triangles: scene.triangles.clone(),
            vertex_normals,
            bvh,
            samples,
            table,
            estimator: sampling.estimator(),
            tangent_to_world: EulerShRotation::new(bands),
            turns: None,
        }
    }

    pub fn view(&self) -> DirectInputs<'_> {
        DirectInputs {
            origins: &self.origins,
            normals: &self.normals,
            triangles: &self.triangles,
            vertex_normals: &self.vertex_normals,
            bvh: &self.bvh,
            samples: &self.samples,
            table: &self.table,
            estimator: self.estimator,
            tangent_to_world: &self.tangent_to_world,
            turns: self.turns,
        }
    }
}

/// Every receiver's ray start moved off its surface along its normal, where its rays start
/// (`extent`: the scene's, which sets the offset's floor).
pub fn ray_origins(starts: &[Vec3], normals: &[Vec3], extent: f32) -> Vec<Vec3> {
    starts
        .iter()
        .zip(normals)
        .map(|(&p, &n)| offset_ray_origin(p, n, extent))
        .collect()
}
