// Responses: one invocation per (member, channel): the mean's response plus the stored
// responses of the receiver cluster's kept terms dotted with their coordinates, written to the
// member's receiver.
// `member_info[i]` = (receiver, receiver cluster, first float of the member's responses, 0).

@group(0) @binding(1) var<storage, read> member_info: array<vec4<u32>>;
@group(0) @binding(2) var<storage, read> terms: array<u32>;
@group(0) @binding(3) var<storage, read> term_offsets: array<u32>;
@group(0) @binding(4) var<storage, read> responses: array<f32>;
@group(0) @binding(5) var<storage, read> mean_response: array<f32>;
@group(0) @binding(6) var<storage, read> coordinates: array<f32>;
@group(0) @binding(7) var<storage, read_write> indirect: array<f32>;

@compute @workgroup_size(WORKGROUP_SIZE, 1, 1)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let index = id.x;
    if (index >= params.members * 3u) {
        return;
    }
    let info = member_info[index / 3u];
    let channel = index % 3u;
    let first_term = term_offsets[info.y];
    let width = term_offsets[info.y + 1u] - first_term;
    let row = info.z + channel * width;
    let begin = min(params.entry_begin, width);
    let end = min(begin + params.entry_limit, width);
    var total = 0.0;
    for (var j = begin; j < end; j += 1u) {
        total += responses[row + j] * coordinates[terms[first_term + j]];
    }
    let out = info.x * 3u + channel;
    if (params.accumulate != 0u) {
        total += indirect[out];
    } else {
        total += mean_response[out];
    }
    indirect[out] = total;
}
