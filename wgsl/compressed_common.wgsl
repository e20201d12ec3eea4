// The compressed direct-to-indirect operator for one frame, in two kernels
// (compressed_project.wgsl, compressed_respond.wgsl). Rust twin:
// local::operator::CompressedOperator::indirect. Every loop sums at most `entry_limit` terms
// per pass (`entry_begin` advances, `accumulate` adds to the previous pass), keeping each
// invocation far below llvmpipe's iteration cap.

struct CompressedParams {
    clusters: u32,
    components: u32,
    members: u32,
    entry_begin: u32,
    entry_limit: u32,
    accumulate: u32,
    pad0: u32,
    pad1: u32,
}

@group(0) @binding(0) var<uniform> params: CompressedParams;
