// Preview rasterisation of a relit mesh: the per-vertex exit radiance computed on the host
// (render::relight) is interpolated across each triangle (Gouraud shading, as in the PRT
// tutorial's vertex-shader dot product) and written unclamped into a float target, so the
// host reads back linear HDR radiance and tone maps it afterwards.

struct RenderParams {
    clip_from_world: mat4x4<f32>,
}

@group(0) @binding(0) var<uniform> params: RenderParams;

struct Varyings {
    @builtin(position) clip: vec4<f32>,
    @location(0) radiance: vec3<f32>,
}

@vertex
fn vs_main(@location(0) position: vec3<f32>, @location(1) radiance: vec3<f32>) -> Varyings {
    var out: Varyings;
    out.clip = params.clip_from_world * vec4<f32>(position, 1.0);
    out.radiance = radiance;
    return out;
}

// Alpha 1 marks covered pixels; the clear colour leaves 0 elsewhere, so previews composite
// over any background.
@fragment
fn fs_main(in: Varyings) -> @location(0) vec4<f32> {
    return vec4<f32>(in.radiance, 1.0);
}
