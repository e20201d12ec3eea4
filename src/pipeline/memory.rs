//! What a bake needs in memory, estimated before it starts, and how it fits a limit: whole,
//! streamed in chunks of receivers, or a least-squares fit's points baked in runs.

use super::scene_media;
use crate::bake;
use crate::bake::stream::{format_bytes, MemoryNeed};
use crate::compress;
use crate::error::Error;
use crate::local::{self, LocalOptions};
use crate::probes;
use crate::receivers::spread_point_count;
use crate::scene::gltf::GltfScene;
use crate::scene::Scene;
use crate::sh::coeff_count;
use crate::spec::{BakeSpec, Compression};
use crate::Result;

/// How a bake fits the memory it may use.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct MemoryPlan {
    /// Streamed in chunks of this many receivers (`None`: whole).
    pub chunk: Option<usize>,
    /// A least-squares fit's points baked about this many at a time, the rest of the bake
    /// whole ([`super::Planned::with_point_chunk`]).
    pub point_chunk: Option<usize>,
    /// A lightmap's texels baked into a scratch file and cleaned up in groups of
    /// coefficients, the rest of the bake whole ([`super::Planned::with_texel_groups`]).
    pub texel_groups: Option<bake::texels::TexelGroups>,
    /// What to tell the user: a `note:` that the bake streams, or a `warning:` that it needs
    /// more than the machine has.
    pub message: Option<String>,
}

/// How the bake of `scene` (`gltf` its document where the scene is a glTF one) as `spec` asks
/// fits `limit` (the user's `--memory-limit`) or, without one, the machine's `available`
/// memory: whole, or streamed to the file in chunks that fit. A bake that cannot fit an
/// explicit limit fails before it starts, saying what it needs; over the available memory, a
/// warning.
pub fn plan_memory(
    spec: &BakeSpec,
    (scene, gltf): (&Scene, Option<&GltfScene>),
    limit: Option<u64>,
    available: Option<u64>,
) -> Result<MemoryPlan> {
    if let Some(options) = &spec.local {
        return local_plan(local_memory_need(options, scene), limit, available);
    }
    let need = memory_need(spec, (scene, gltf));
    let Some(over) = over_budget(need, spec, (scene, gltf), limit, available) else {
        return Ok(MemoryPlan::default());
    };
    let options = spec.options();
    let chunkable = !over.scatters;
    let streamable = bake::stream::streams(&options) && chunkable;
    let points_chunk =
        options.fit == bake::Fit::LeastSquares && options.lightmap.is_none() && chunkable;
    if spec.receivers.lightmap.is_some() && chunkable {
        return over.lightmap_held("baking");
    }
    if points_chunk {
        return over.points_in_runs("bake", "baking");
    }
    if !streamable {
        return over.refuse_or_warn("bake", why_whole(over.scatters));
    }
    over.streamed("the transfer")
}

/// A local-lights bake runs whole: it holds the example lights' bounced light, its gather
/// matrix and depth maps for every receiver at once. Over an explicit limit it is refused,
/// saying what it needs; over the machine's available memory, a warning.
fn local_plan(need: u64, limit: Option<u64>, available: Option<u64>) -> Result<MemoryPlan> {
    let Some(budget) = limit.or(available).filter(|&budget| need > budget) else {
        return Ok(MemoryPlan::default());
    };
    let why = "it holds the example lights' bounced light, its gather matrix and depth maps \
               for every receiver at once, so it does not stream";
    refuse_or_warn("local-lights bake", need, (budget, limit.is_some()), why)
}

/// The end of a `what` (a bake, a merge) that needs `need` bytes and cannot be split, for the
/// reason `why`: over an `explicit` limit `budget`, refused in one line; over the machine's
/// memory, run whole with a warning.
fn refuse_or_warn(
    what: &str,
    need: u64,
    (budget, explicit): (u64, bool),
    why: &str,
) -> Result<MemoryPlan> {
    let (need, budget) = (format_bytes(need), format_bytes(budget));
    if explicit {
        return Err(Error::Options(format!(
            "--memory-limit {budget}: this {what} needs about {need}, and {why}"
        )));
    }
    Ok(MemoryPlan {
        message: Some(format!(
            "warning: this {what} needs about {need}, more than the {budget} this machine has \
             available, and {why}"
        )),
        ..MemoryPlan::default()
    })
}

/// The memory a local-lights bake of `scene` with `options` needs, estimated before it starts:
/// the gather bake's inputs and matrix (`MemoryNeed` of `local::gather_options`), and what
/// `local::memory_need` counts.
pub fn local_memory_need(options: &LocalOptions, scene: &Scene) -> u64 {
    let (vertices, triangles) = (scene.vertex_count(), scene.triangle_count());
    let gather = MemoryNeed::estimate(vertices, triangles, &local::gather_options(options));
    gather.whole() + local::memory_need(vertices as u64, options)
}

/// How a merge of a sharded bake (`prt-gpu merge`) fits `limit` or the machine's `available`
/// memory, its parts read one at a time (the largest taking `largest_part` bytes): a bake at
/// the vertices streams in chunks, a least-squares fit's points are read in runs, and a
/// lightmap's texels are held in a scratch file; subsurface scattering is joined whole, so a
/// limit below it is refused.
pub fn plan_merge_memory(
    spec: &BakeSpec,
    (scene, gltf): (&Scene, Option<&GltfScene>),
    largest_part: u64,
    limit: Option<u64>,
    available: Option<u64>,
) -> Result<MemoryPlan> {
    let need = memory_need(spec, (scene, gltf)).with_merge_part(largest_part);
    let Some(over) = over_budget(need, spec, (scene, gltf), limit, available) else {
        return Ok(MemoryPlan::default());
    };
    if over.scatters {
        return over.refuse_or_warn("merge", why_whole(true));
    }
    if spec.receivers.lightmap.is_some() {
        return over.lightmap_held("reading");
    }
    if spec.options().fit == bake::Fit::LeastSquares {
        return over.points_in_runs("merge", "reading");
    }
    over.streamed("the merge")
}

/// A bake whose need is over its budget: the user's limit or, without one, the machine's
/// available memory.
struct OverBudget {
    need: MemoryNeed,
    budget: u64,
    /// The budget is the user's `--memory-limit`, which a bake may not exceed.
    explicit: bool,
    /// The bake scatters light under the surface (`--subsurface`, or a glTF scene's translucent
    /// medium): what a chunked bake cannot give, the medium's scattering matrices.
    scatters: bool,
}

/// The bake of `scene` as `spec` asks, which needs `need`, where that is over `limit` or the
/// machine's `available` memory; `None` where it fits whole (or nothing is known of the
/// machine).
fn over_budget(
    need: MemoryNeed,
    spec: &BakeSpec,
    (scene, gltf): (&Scene, Option<&GltfScene>),
    limit: Option<u64>,
    available: Option<u64>,
) -> Option<OverBudget> {
    let budget = limit.or(available)?;
    if need.whole() <= budget {
        return None;
    }
    let translucent =
        gltf.is_some_and(|gltf| scene_media(spec, (scene, gltf), &mut Vec::new()).is_some());
    Some(OverBudget {
        need,
        budget,
        explicit: limit.is_some(),
        scatters: spec.transfer.subsurface.is_some() || translucent,
    })
}

impl OverBudget {
    /// The plan of a bake that streams `what` in the largest chunks that fit its budget.
    fn streamed(&self, what: &str) -> Result<MemoryPlan> {
        let (need, budget) = (&self.need, self.budget);
        let chunk = need.chunk_within(budget)?;
        Ok(MemoryPlan {
            chunk: Some(chunk),
            message: Some(format!(
                "note: streaming {what} in chunks of {chunk} receivers to stay within {} (about \
                 {} whole, {} streamed)",
                format_bytes(budget),
                format_bytes(need.whole()),
                format_bytes(need.streamed(chunk))
            )),
            ..MemoryPlan::default()
        })
    }

    /// The end of a `what` (a bake, a merge) that cannot be split, for the reason `why`: over
    /// an explicit limit, refused in one line; over the machine's memory, run whole with a
    /// warning.
    fn refuse_or_warn(&self, what: &str, why: &str) -> Result<MemoryPlan> {
        let budget = (self.budget, self.explicit);
        refuse_or_warn(what, self.need.whole(), budget, why)
    }

    /// The plan of a least-squares `what` (a bake, a merge) over its budget: the fit's points
    /// `doing` (baked, read from the parts) in the largest runs that fit. Over an explicit
    /// limit even in the smallest runs, an error; over the machine's memory, those and a
    /// warning.
    fn points_in_runs(&self, what: &str, doing: &str) -> Result<MemoryPlan> {
        let (need, budget) = (&self.need, self.budget);
        let points = need.fit.map_or(0, |fit| fit.points);
        match (need.point_chunk_within(budget), self.explicit) {
            (Ok(chunk), _) => Ok(MemoryPlan {
                point_chunk: Some(chunk),
                message: Some(format!(
                    "note: {doing} the least-squares fit's {points} points in runs of about \
                     {chunk} to stay within {} (about {} whole, {} so)",
                    format_bytes(budget),
                    format_bytes(need.whole()),
                    format_bytes(need.points_chunked(chunk))
                )),
                ..MemoryPlan::default()
            }),
            (Err(error), true) => Err(error),
            // Over the machine's memory even in the smallest runs: those, and a warning.
            (Err(_), false) => Ok(MemoryPlan {
                point_chunk: Some(bake::stream::MIN_CHUNK),
                message: Some(format!(
                    "warning: this {what} needs at least {} with its fit's points in runs, \
                     more than the {} this machine has available",
                    format_bytes(need.points_chunked(bake::stream::MIN_CHUNK)),
                    format_bytes(budget)
                )),
                ..MemoryPlan::default()
            }),
        }
    }

    /// The plan of a lightmap bake over its budget: its texels held in a scratch file, cleaned
    /// up as many coefficients at a time as fit, and a least-squares fit's points at the
    /// vertices `doing` (baked, read from a merge's parts) in runs where, whole, they would not
    /// fit beside it. Over an explicit limit even one at a time, an error; over the machine's
    /// memory, one at a time and a warning.
    fn lightmap_held(&self, doing: &str) -> Result<MemoryPlan> {
        let budget = self.budget;
        // A least-squares fit at the vertices bakes (or a merge reads it) before the lightmap,
        // whole; where that alone breaks the budget, its points go in runs, as they do without
        // a lightmap.
        let fit_run = match self.need.lightmap_held(1) > budget {
            true => self
                .need
                .fit_run_within(self.need.beside_lightmap(), budget),
            false => None,
        };
        let need = &match fit_run {
            Some(run) => self.need.with_fit_run(run),
            None => self.need,
        };
        let point_chunk = fit_run.map(|run| run as usize);
        let groups = match (need.texel_groups_within(budget), self.explicit) {
            (Ok(groups), _) => groups,
            (Err(error), true) => return Err(error),
            (Err(_), false) => {
                let groups = bake::texels::TexelGroups {
                    chunk: need
                        .lightmap
                        .map_or(bake::stream::MIN_CHUNK, |l| l.chunk(1)),
                    columns: 1,
                };
                return Ok(MemoryPlan {
                    point_chunk,
                    texel_groups: Some(groups),
                    message: Some(format!(
                        "warning: this bake needs at least {} with its lightmap held in a \
                         scratch file, more than the {} this machine has available",
                        format_bytes(need.lightmap_held(1)),
                        format_bytes(budget)
                    )),
                    ..MemoryPlan::default()
                });
            }
        };
        let runs = point_chunk.map_or(String::new(), |run| {
            format!(", and {doing} the vertices' least-squares points in runs of {run}")
        });
        Ok(MemoryPlan {
            point_chunk,
            texel_groups: Some(groups),
            message: Some(format!(
                "note: holding the lightmap's texels in a scratch file, cleaned up {} \
                 coefficients at a time{runs}, to stay within {} (about {} whole, {} so)",
                groups.columns,
                format_bytes(budget),
                format_bytes(need.whole()),
                format_bytes(need.lightmap_held(groups.columns as u64))
            )),
            ..MemoryPlan::default()
        })
    }
}

/// Why a bake that needs more than its limit is not split: what it does that needs every
/// receiver at once.
fn why_whole(scatters: bool) -> &'static str {
    if scatters {
        "subsurface scattering carries light from every vertex to those around it over the \
         whole surface, so it does not stream in chunks"
    } else {
        "only bakes at the vertices or at a least-squares fit's points stream in chunks"
    }
}

/// The memory the bake of `scene` (`gltf` its document where the scene is a glTF one) as
/// `spec` asks needs, estimated before it starts ([`MemoryNeed`]): what [`plan_memory`] holds
/// against the user's limit or the machine's memory.
pub fn memory_need(spec: &BakeSpec, (scene, gltf): (&Scene, Option<&GltfScene>)) -> MemoryNeed {
    let options = spec.options();
    let probes = spec.probes.as_ref().map_or(0, |probes| {
        let interreflected = options.mode == bake::Mode::Interreflected;
        probes::memory_need(
            probes,
            scene,
            (options.bands, options.samples),
            interreflected,
        )
    });
    let mut need = MemoryNeed::estimate(scene.vertex_count(), scene.triangle_count(), &options)
        .with_document(gltf.map_or(0, GltfScene::byte_size))
        .with_probes(probes);
    if let Some(zonal) = spec.storage.zonal {
        need = need.with_zonal(zonal.bands);
    }
    if options.fit == bake::Fit::LeastSquares {
        let points = spread_point_count(scene, options.point_density);
        need = need.with_fit_points(points as u64, &options);
    }
    if let Some(size) = spec.receivers.lightmap {
        need = need.with_lightmap(size, &options);
    }
    if let Some(compression) = spec.compression() {
        // RGB: a lean bake may keep three channels where its albedo is coloured.
        let dimension = 3 * coeff_count(options.bands);
        let vertices = scene.vertex_count();
        let (clusters, components) = match compression {
            Compression::Shape {
                clusters,
                components,
            } => (clusters as usize, components as usize),
            // The largest shape the search may try.
            Compression::Target { .. } => compress::largest_search_shape(dimension, vertices),
        };
        let group = compress::covariance_group(dimension) as u64;
        need = need.with_compression(
            (clusters as u64, components as u64),
            dimension as u64,
            (group, compress::RECONSTRUCTED_ROWS as u64),
        );
    }
    need
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{builtin, prepare::prepare};

    /// A least-squares lightmap over its limit is held as one fitted by points is, and its
    /// need held counts the fit: more than the same map's by points, less than it whole.
    #[test]
    fn a_least_squares_lightmap_over_its_limit_is_held() {
        let scene = prepare(builtin::default_scene()).unwrap().0;
        let mut spec = BakeSpec::default();
        spec.receivers.lightmap = Some(256);
        let at = (&scene, None);
        let by_points = memory_need(&spec, at);
        spec.receivers.fit = bake::Fit::LeastSquares;
        let fitted = memory_need(&spec, at);
        assert!(fitted.lightmap_held(4) > by_points.lightmap_held(4));
        assert!(fitted.lightmap_held(4) < fitted.whole());
        let limit = fitted.lightmap_held(4);
        let held = plan_memory(&spec, at, Some(limit), None).unwrap();
        let groups = held.texel_groups.expect("held");
        assert!(groups.columns >= 4, "{groups:?}");
        let merged = plan_merge_memory(&spec, at, 1 << 10, Some(limit), None).unwrap();
        assert!(merged.texel_groups.is_some(), "{:?}", merged.message);
        // Below one coefficient at a time (the vertices' fit in its smallest runs), the refusal
        // names the fit.
        let smallest = fitted.with_fit_run(bake::stream::MIN_CHUNK as u64);
        let refused =
            plan_memory(&spec, at, Some(smallest.lightmap_held(1) - 1), None).unwrap_err();
        assert!(
            refused
                .to_string()
                .contains("the least-squares fit's points"),
            "{refused}"
        );
    }

    /// Beside a held lightmap, a least-squares fit at the vertices that alone would break the
    /// limit bakes its points in runs, as it does without a lightmap (a merge reads them so).
    #[test]
    fn a_fit_too_large_beside_a_held_lightmap_bakes_its_points_in_runs() {
        let scene = prepare(builtin::default_scene()).unwrap().0;
        let mut spec = BakeSpec::default();
        spec.receivers.lightmap = Some(64);
        spec.receivers.fit = bake::Fit::LeastSquares;
        spec.transfer.mode = bake::Mode::Interreflected;
        let at = (&scene, None);
        let need = memory_need(&spec, at);
        let limit = need.with_fit_run(1024).lightmap_held(4);
        assert!(limit < need.lightmap_held(1), "the fit whole fits");
        let plan = plan_memory(&spec, at, Some(limit), None).unwrap();
        let run = plan.point_chunk.expect("the fit's points in runs") as u64;
        assert!(run >= 1024, "{run}");
        assert!(need.with_fit_run(run).lightmap_held(4) <= limit);
        assert!(plan.texel_groups.expect("held").columns >= 4);
        assert!(plan.message.unwrap().contains(&format!("in runs of {run}")));
        // Without room for the smallest run, the refusal names the runs.
        let smallest = need.with_fit_run(bake::stream::MIN_CHUNK as u64);
        let below = smallest.lightmap_held(1) - 1;
        let refused = plan_memory(&spec, at, Some(below), None).unwrap_err();
        assert!(
            refused.to_string().contains("in runs of 256 points"),
            "{refused}"
        );
        // A merge reads the points from its parts in runs the same way.
        let merged = plan_merge_memory(&spec, at, 1 << 10, Some(limit), None).unwrap();
        assert!(merged.point_chunk.is_some() && merged.texel_groups.is_some());
    }
}
