// Lightmap denoising: one invocation per (texel of a band of rows, group of coefficients);
// each texel becomes the weighted mean of the texels of its chart within DENOISE_RADIUS, the
// weights from position, normal, chart and level against noise. Rust twin: receivers::denoise::denoise, the
// footprint summed in the same order. An invocation runs at most FOOTPRINT_TEXELS x
// (COEFFS_PER_INVOCATION + 1) + COEFFS_PER_INVOCATION loop iterations, far below llvmpipe's cap.

struct DenoiseParams {
    width: u32,
    height: u32,
    // Floats per texel.
    stride: u32,
    // The rows this pass writes: row_first .. row_first + row_count.
    row_first: u32,
    row_count: u32,
    // The first row the guide and image buffers hold.
    input_row_first: u32,
    texel_length: f32,
    pad0: u32,
}

@group(0) @binding(0) var<uniform> params: DenoiseParams;
// xyz: the texel's position; w: its level.
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
// xyz: its normal; w: its level's noise.
@group(0) @binding(2) var<storage, read> normals: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> charts: array<u32>;
@group(0) @binding(4) var<storage, read> image: array<f32>;
@group(0) @binding(5) var<storage, read_write> denoised: array<f32>;

// Rust twin: receivers::denoise::spatial_weight.
fn spatial_weight(dx: i32, dy: i32) -> f32 {
    let reach = f32(DENOISE_RADIUS + 1u);
    let falloff = max(1.0 - f32(dx * dx + dy * dy) / (reach * reach), 0.0);
    return falloff * falloff;
}

// Rust twin: receivers::denoise::plane_weight.
fn plane_weight(height: f32, texel_length: f32) -> f32 {
    let relative = height / texel_length;
    let falloff = max(1.0 - relative * relative, 0.0);
    return falloff * falloff;
}

// Rust twin: receivers::denoise::normal_weight.
fn normal_weight(cosine: f32) -> f32 {
    var weight = max(cosine, 0.0);
    for (var i = 0u; i < NORMAL_POWER_SQUARINGS; i++) {
        weight *= weight;
    }
    return weight;
}

// Rust twin: receivers::denoise::range_weight.
fn range_weight(difference: f32, noise_a: f32, noise_b: f32) -> f32 {
    let scale = RANGE_SIGMAS * RANGE_SIGMAS * (noise_a * noise_a + noise_b * noise_b);
    let falloff = max(1.0 - difference * difference / scale, 0.0);
    return falloff * falloff;
}

// Rust twin: receivers::denoise::DenoiseGuide::weight (texels as indices into this pass's
// buffers).
fn weight(texel: u32, neighbour: u32, dx: i32, dy: i32) -> f32 {
    if (charts[neighbour] != charts[texel] || charts[texel] == NO_CHART) {
        return 0.0;
    }
    let normal = normals[texel].xyz;
    let along_normal = dot(normal, positions[neighbour].xyz - positions[texel].xyz);
    return spatial_weight(dx, dy) * plane_weight(along_normal, params.texel_length)
        * normal_weight(dot(normal, normals[neighbour].xyz))
        * range_weight(positions[neighbour].w - positions[texel].w, normals[texel].w, normals[neighbour].w);
}

@compute @workgroup_size(WORKGROUP_SIZE, 1, 1)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let width = params.width;
    if (id.x >= params.row_count * width) {
        return;
    }
    let x = id.x % width;
    let y = params.row_first + id.x / width;
    let first_coeff = id.y * COEFFS_PER_INVOCATION;
    let coeffs = min(COEFFS_PER_INVOCATION, params.stride - min(first_coeff, params.stride));
    let texel = (y - params.input_row_first) * width + x;
    let out = (id.x * params.stride) + first_coeff;
    let own_values = texel * params.stride + first_coeff;
    if (charts[texel] == NO_CHART) {
        for (var k = 0u; k < coeffs; k++) {
            denoised[out + k] = image[own_values + k];
        }
        return;
    }
    let radius = i32(DENOISE_RADIUS);
    var total = 0.0;
    var sums: array<f32, COEFFS_PER_INVOCATION>;
    for (var dy = -radius; dy <= radius; dy++) {
        for (var dx = -radius; dx <= radius; dx++) {
            let fx = i32(x) + dx;
            let fy = i32(y) + dy;
            if (fx < 0 || fy < 0 || fx >= i32(width) || fy >= i32(params.height)) {
                continue;
            }
            let neighbour = u32(fy - i32(params.input_row_first)) * width + u32(fx);
            let w = weight(texel, neighbour, dx, dy);
            if (w > 0.0) {
                total += w;
                let values = neighbour * params.stride + first_coeff;
                for (var k = 0u; k < coeffs; k++) {
                    sums[k] += w * image[values + k];
                }
            }
        }
    }
    for (var k = 0u; k < coeffs; k++) {
        denoised[out + k] = sums[k] / total;
    }
}
