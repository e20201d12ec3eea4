//! WGSL sources, assembled from `wgsl/` with the constants they share with Rust generated from
//! the Rust definitions (no "keep in sync" comments).

use crate::bvh::gpu::{EMPTY_CHILD, LAST_IN_LEAF, LEAF_FLAG, WIDE_STACK_SIZE};
use crate::ray::{MIN_DIRECTION_COMPONENT, NO_HIT, RAY_T_MAX, SLAB_WIDENING, TIE_REACH};

/// Invocations per workgroup of every kernel.
pub const WORKGROUP_SIZE: u32 = 64;

/// End of a vertex's list in the visibility kernel's `sample_lists` (the horizon pass writes
/// the lists, wgsl/horizon.wgsl).
pub const NO_SAMPLE: u32 = u32::MAX;

/// `ProjectParams::estimator` flag: sum over the blocked samples above the horizon instead of
/// the visible ones (`sampling::Estimator::Blocked`, the control variate).
pub const ESTIMATOR_BLOCKED: u32 = 1;
/// `ProjectParams::estimator` flag: directions in the tangent frame with cosine density, so the
/// sum carries no cosine factor (`sampling::DirectionFrame::Tangent`).
pub const ESTIMATOR_TANGENT: u32 = 2;

/// `VisibilityParams::frames` and `HorizonParams::frames`: sample directions are world
/// directions (`sampling::DirectionFrame::World`).
pub const FRAMES_WORLD: u32 = 0;
/// Directions are in each receiver's tangent frame (`sampling::tangent_frame`).
pub const FRAMES_TANGENT: u32 = 1;
/// Directions are in each receiver's tangent frame turned by its own angle
/// (`sampling::ReceiverTurns`).
pub const FRAMES_TURNED: u32 = 2;

const BVH_WGSL: &str = include_str!("../wgsl/bvh.wgsl");
const SAMPLES_WGSL: &str = include_str!("../wgsl/samples.wgsl");
const HORIZON_WGSL: &str = include_str!("../wgsl/horizon.wgsl");
const VISIBILITY_WGSL: &str = include_str!("../wgsl/visibility.wgsl");
const PROJECT_WGSL: &str = include_str!("../wgsl/project.wgsl");
const GATHER_WGSL: &str = include_str!("../wgsl/gather.wgsl");
const RENDER_WGSL: &str = include_str!("../wgsl/render.wgsl");
const COMPRESSED_COMMON_WGSL: &str = include_str!("../wgsl/compressed_common.wgsl");
const COMPRESSED_PROJECT_WGSL: &str = include_str!("../wgsl/compressed_project.wgsl");
const COMPRESSED_RESPOND_WGSL: &str = include_str!("../wgsl/compressed_respond.wgsl");
const PROBES_RELIGHT_WGSL: &str = include_str!("../wgsl/probes_relight.wgsl");
const CPCA_ASSIGN_WGSL: &str = include_str!("../wgsl/cpca_assign.wgsl");
const DENOISE_WGSL: &str = include_str!("../wgsl/denoise.wgsl");

/// Coefficients one invocation of the denoising kernel sums (its private array's length).
pub const COEFFS_PER_INVOCATION: u32 = 64;

/// Constants every kernel sees. `{:?}` prints the shortest decimal that parses back to the
/// same f32, so WGSL gets the exact Rust values.
fn prelude() -> String {
    format!(
        "// Generated from Rust by src/shaders.rs.\n\
         const WIDE_STACK_SIZE: u32 = {WIDE_STACK_SIZE}u;\n\
         const WORKGROUP_SIZE: u32 = {WORKGROUP_SIZE}u;\n\
         const SLAB_WIDENING: f32 = {SLAB_WIDENING:?};\n\
         const TIE_REACH: f32 = {TIE_REACH:?};\n\
         const MIN_DIRECTION_COMPONENT: f32 = {MIN_DIRECTION_COMPONENT:?};\n\
         const RAY_T_MAX: f32 = {RAY_T_MAX:?};\n\
         const NO_HIT: u32 = {NO_HIT}u;\n\
         const LEAF_FLAG: u32 = {LEAF_FLAG}u;\n\
         const EMPTY_CHILD: u32 = {EMPTY_CHILD}u;\n\
         const LAST_IN_LEAF: u32 = {LAST_IN_LEAF}u;\n\
         const NO_SAMPLE: u32 = {NO_SAMPLE}u;\n\
         const ESTIMATOR_BLOCKED: u32 = {ESTIMATOR_BLOCKED}u;\n\
         const ESTIMATOR_TANGENT: u32 = {ESTIMATOR_TANGENT}u;\n\
         const FRAMES_TANGENT: u32 = {FRAMES_TANGENT}u;\n\
         const FRAMES_TURNED: u32 = {FRAMES_TURNED}u;\n\n"
    )
}

/// The horizon kernel: the visibility kernel's sample lists (the BVH's rounding included).
pub fn horizon_kernel() -> String {
    format!("{}{BVH_WGSL}\n{SAMPLES_WGSL}\n{HORIZON_WGSL}", prelude())
}

/// A kernel of the traversal's arithmetic alone: for each operand pair `(a, b)`,
/// `(divide_rounded(a, b), rounded(a * b))` (`bake::gpu::Division` probes an adapter with it).
pub fn arithmetic_kernel() -> String {
    const KERNEL: &str = "
@group(0) @binding(0) var<storage, read> triangles: array<vec4<u32>>;
@group(0) @binding(1) var<storage, read> operands: array<vec2<f32>>;
@group(0) @binding(2) var<storage, read_write> results: array<vec2<f32>>;
// Declared for the traversal, which this kernel does not call (so it is not bound).
@group(0) @binding(3) var<storage, read> nodes: array<vec4<u32>>;

@compute @workgroup_size(WORKGROUP_SIZE, 1, 1)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    read_unseen_zero();
    if (id.x < arrayLength(&operands)) {
        let o = operands[id.x];
        results[id.x] = vec2<f32>(divide_rounded(o.x, o.y), rounded(o.x * o.y));
    }
}
";
    format!("{}{BVH_WGSL}\n{KERNEL}", prelude())
}

/// The visibility kernel (BVH traversal included).
pub fn visibility_kernel() -> String {
    format!("{}{BVH_WGSL}\n{SAMPLES_WGSL}\n{VISIBILITY_WGSL}", prelude())
}

/// The projection kernel.
pub fn project_kernel() -> String {
    format!("{}{PROJECT_WGSL}", prelude())
}

/// The compressed operator's projection kernel (local lights).
pub fn compressed_project_kernel() -> String {
    format!(
        "{}{COMPRESSED_COMMON_WGSL}\n{COMPRESSED_PROJECT_WGSL}",
        prelude()
    )
}

/// The compressed operator's response kernel (local lights).
pub fn compressed_respond_kernel() -> String {
    format!(
        "{}{COMPRESSED_COMMON_WGSL}\n{COMPRESSED_RESPOND_WGSL}",
        prelude()
    )
}

/// The kernel relighting probes for a frame.
pub fn probes_relight_kernel() -> String {
    format!("{}{PROBES_RELIGHT_WGSL}", prelude())
}

/// The bounce (gather) kernel.
pub fn gather_kernel() -> String {
    format!("{}{GATHER_WGSL}", prelude())
}

/// The CPCA assignment kernel (`compress::gpu`).
pub fn cpca_assign_kernel() -> String {
    format!("{}{CPCA_ASSIGN_WGSL}", prelude())
}

/// The lightmap denoising kernel (`bake::gpu::denoise`), with the filter's constants.
pub fn denoise_kernel() -> String {
    use crate::receivers::denoise::{
        DENOISE_RADIUS, NORMAL_POWER_SQUARINGS, NO_CHART, RANGE_SIGMAS,
    };
    format!(
        "{}const DENOISE_RADIUS: u32 = {DENOISE_RADIUS}u;\n\
         const NO_CHART: u32 = {NO_CHART}u;\n\
         const NORMAL_POWER_SQUARINGS: u32 = {NORMAL_POWER_SQUARINGS}u;\n\
         const COEFFS_PER_INVOCATION: u32 = {COEFFS_PER_INVOCATION}u;\n\
         const RANGE_SIGMAS: f32 = {RANGE_SIGMAS:?};\n\n{DENOISE_WGSL}",
        prelude()
    )
}

/// The preview renderer's vertex and fragment shaders.
pub fn render_shader() -> String {
    format!("{}{RENDER_WGSL}", prelude())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bake::bounce::Hit;
    use crate::bake::gpu::denoise::DenoiseParams;
    use crate::bake::gpu::{GatherParams, HorizonParams, ProjectParams, VisibilityParams};
    use crate::bvh::gpu::{GpuChild, GpuNode, WIDTH};
    use crate::bvh::BvhTriangle;
    use crate::compress::gpu::AssignParams;
    use crate::local::gpu::CompressedParams;
    use crate::render::RenderParams;
    use std::mem::{offset_of, size_of};

    fn parse(source: &str) -> naga::Module {
        let module = naga::front::wgsl::parse_str(source)
            .unwrap_or_else(|e| panic!("WGSL does not parse:\n{}", e.emit_to_string(source)));
        naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::empty(),
        )
        .validate(&module)
        .unwrap_or_else(|e| panic!("WGSL does not validate:\n{}", e.emit_to_string(source)));
        module
    }

    /// (size, [(member, offset)]) of a WGSL struct, from naga's layout.
    fn wgsl_layout(module: &naga::Module, name: &str) -> (u32, Vec<(String, u32)>) {
        for (_, ty) in module.types.iter() {
            if ty.name.as_deref() == Some(name) {
                if let naga::TypeInner::Struct { members, span } = &ty.inner {
                    let fields = members
                        .iter()
                        .map(|m| (m.name.clone().unwrap_or_default(), m.offset))
                        .collect();
                    return (*span, fields);
                }
            }
        }
        panic!("struct {name} not found in WGSL");
    }

    macro_rules! rust_layout {
        ($ty:ty, $($field:ident),+) => {
            (
                size_of::<$ty>() as u32,
                vec![$((stringify!($field).to_string(), offset_of!($ty, $field) as u32)),+],
            )
        };
    }

    /// `rounded` reads a private zero that only `read_unseen_zero` sets (wgsl/bvh.wgsl): a
    /// kernel that rounds without calling it first would round through a zero the compiler
    /// sees, and a driver could fuse its products again.
    #[test]
    fn every_kernel_that_rounds_reads_its_unseen_zero_first() {
        for (name, kernel) in [
            ("arithmetic", arithmetic_kernel()),
            ("horizon", horizon_kernel()),
            ("visibility", visibility_kernel()),
        ] {
            let main = &kernel[kernel.find("fn main(").unwrap()..];
            let body = &main[main.find('{').unwrap() + 1..];
            assert!(
                body.trim_start().starts_with("read_unseen_zero();"),
                "{name}: main does not begin with read_unseen_zero()"
            );
        }
        for kernel in [
            project_kernel(),
            gather_kernel(),
            render_shader(),
            cpca_assign_kernel(),
            denoise_kernel(),
        ] {
            assert!(
                !kernel.contains("rounded("),
                "a kernel rounds without the traversal's zero"
            );
        }
    }

    #[test]
    fn every_kernel_parses_and_validates() {
        parse(&arithmetic_kernel());
        parse(&horizon_kernel());
        parse(&visibility_kernel());
        parse(&project_kernel());
        parse(&gather_kernel());
        parse(&render_shader());
        parse(&compressed_project_kernel());
        parse(&compressed_respond_kernel());
        parse(&cpca_assign_kernel());
        parse(&probes_relight_kernel());
        parse(&denoise_kernel());
    }

    #[test]
    fn probe_relight_params_match_their_wgsl_twin() {
        use crate::probes::gpu::ProbeRelightParams;
        assert_eq!(
            wgsl_layout(&parse(&probes_relight_kernel()), "ProbeRelightParams"),
            rust_layout!(
                ProbeRelightParams,
                probes,
                rows,
                coeffs,
                channels,
                first_probe,
                pad0,
                pad1,
                pad2
            )
        );
    }

    #[test]
    fn shared_structs_match_their_wgsl_twins() {
        for kernel in [compressed_project_kernel(), compressed_respond_kernel()] {
            assert_eq!(
                wgsl_layout(&parse(&kernel), "CompressedParams"),
                rust_layout!(
                    CompressedParams,
                    clusters,
                    components,
                    members,
                    entry_begin,
                    entry_limit,
                    accumulate,
                    pad0,
                    pad1
                )
            );
        }
        let visibility = parse(&visibility_kernel());
        let project = parse(&project_kernel());
        // The visibility kernel reads nodes and triangles as vec4<u32> words at these offsets
        // (wgsl/bvh.wgsl).
        assert_eq!(
            rust_layout!(GpuChild, bounds, reference),
            (16, vec![("bounds".into(), 0), ("reference".into(), 12)])
        );
        assert_eq!(
            rust_layout!(GpuNode, children),
            (16 * WIDTH as u32, vec![("children".into(), 0)])
        );
        assert_eq!(
            rust_layout!(BvhTriangle, v0, source_index, v1, last_in_leaf, v2, pad2),
            (
                48,
                vec![
                    ("v0".into(), 0),
                    ("source_index".into(), 12),
                    ("v1".into(), 16),
                    ("last_in_leaf".into(), 28),
                    ("v2".into(), 32),
                    ("pad2".into(), 44)
                ]
            )
        );
        assert_eq!(
            wgsl_layout(&visibility, "VisibilityParams"),
            rust_layout!(
                VisibilityParams,
                vertex_offset,
                vertex_count,
                sample_offset,
                sample_count,
                words_per_vertex,
                max_steps,
                shadowed,
                record_hits,
                grid_origin,
                grid_step,
                frames,
                turn_seed,
                turn_first,
                pad0
            )
        );
        assert_eq!(
            wgsl_layout(&visibility, "Hit"),
            rust_layout!(Hit, triangle, u, v)
        );
        assert_eq!(
            wgsl_layout(&parse(&horizon_kernel()), "HorizonParams"),
            rust_layout!(
                HorizonParams,
                vertex_offset,
                vertex_count,
                sample_offset,
                sample_count,
                frames,
                record_hits,
                turn_seed,
                turn_first
            )
        );
        assert_eq!(
            wgsl_layout(&parse(&gather_kernel()), "GatherParams"),
            rust_layout!(
                GatherParams,
                row_offset,
                row_count,
                coeff_count,
                entry_begin,
                entry_limit,
                accumulate,
                pad0,
                pad1
            )
        );
        assert_eq!(
            wgsl_layout(&parse(&denoise_kernel()), "DenoiseParams"),
            rust_layout!(
                DenoiseParams,
                width,
                height,
                stride,
                row_first,
                row_count,
                input_row_first,
                texel_length,
                pad0
            )
        );
        assert_eq!(
            wgsl_layout(&parse(&cpca_assign_kernel()), "AssignParams"),
            rust_layout!(
                AssignParams,
                vertex_count,
                dimension,
                components,
                cluster_begin,
                cluster_end,
                accumulate,
                pad0,
                pad1
            )
        );
        assert_eq!(
            wgsl_layout(&parse(&render_shader()), "RenderParams"),
            rust_layout!(RenderParams, clip_from_world)
        );
        assert_eq!(
            wgsl_layout(&project, "ProjectParams"),
            rust_layout!(
                ProjectParams,
                vertex_offset,
                vertex_count,
                sample_offset,
                sample_count,
                words_per_vertex,
                coeff_count,
                accumulate,
                estimator
            )
        );
    }

    #[test]
    fn generated_constants_are_exact() {
        let source = prelude();
        let module = parse(&source);
        // Every constant must come back bit-identical after WGSL parsing.
        let mut checked = 0;
        for (_, constant) in module.constants.iter() {
            let name = constant.name.as_deref().unwrap_or_default();
            let (value, expected) = match &module.global_expressions[constant.init] {
                naga::Expression::Literal(naga::Literal::F32(v)) => (
                    v.to_bits(),
                    match name {
                        "SLAB_WIDENING" => SLAB_WIDENING,
                        "TIE_REACH" => TIE_REACH,
                        "MIN_DIRECTION_COMPONENT" => MIN_DIRECTION_COMPONENT,
                        "RAY_T_MAX" => RAY_T_MAX,
                        other => panic!("unexpected f32 constant {other:?}"),
                    }
                    .to_bits(),
                ),
                naga::Expression::Literal(naga::Literal::U32(v)) => (
                    *v,
                    match name {
                        "WIDE_STACK_SIZE" => WIDE_STACK_SIZE as u32,
                        "WORKGROUP_SIZE" => WORKGROUP_SIZE,
                        "NO_HIT" => NO_HIT,
                        "LEAF_FLAG" => LEAF_FLAG,
                        "EMPTY_CHILD" => EMPTY_CHILD,
                        "LAST_IN_LEAF" => LAST_IN_LEAF,
                        "NO_SAMPLE" => NO_SAMPLE,
                        "ESTIMATOR_BLOCKED" => ESTIMATOR_BLOCKED,
                        "ESTIMATOR_TANGENT" => ESTIMATOR_TANGENT,
                        "FRAMES_TANGENT" => FRAMES_TANGENT,
                        "FRAMES_TURNED" => FRAMES_TURNED,
                        other => panic!("unexpected u32 constant {other:?}"),
                    },
                ),
                other => panic!("constant {name} is not a literal: {other:?}"),
            };
            assert_eq!(value, expected, "{name}");
            checked += 1;
        }
        assert_eq!(checked, 15, "expected fifteen generated constants");
    }
}
