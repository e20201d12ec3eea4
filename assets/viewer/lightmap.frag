// The four texels around the pixel's lightmap coordinates, relit (transfer.glsl) and blended
// bilinearly, clamped at the borders: `prt-gpu render`'s lookup (bake::texels::sample_bilinear),
// texel (x, y) centred at ((x + 0.5) / width, (y + 0.5) / height).
uniform ivec2 lightmap_size;
in vec2 lightmap_uv;
out vec4 color;

vec3 relit_texel(ivec2 at) {
    ivec2 clamped = clamp(at, ivec2(0), lightmap_size - 1);
    return relight(clamped.y * lightmap_size.x + clamped.x);
}

void main() {
    vec2 xy = lightmap_uv * vec2(lightmap_size) - 0.5;
    vec2 corner = floor(xy);
    vec2 f = xy - corner;
    ivec2 at = ivec2(corner);
    vec3 top = mix(relit_texel(at), relit_texel(at + ivec2(1, 0)), f.x);
    vec3 bottom = mix(relit_texel(at + ivec2(0, 1)), relit_texel(at + ivec2(1, 1)), f.x);
    color = display_color(mix(top, bottom, f.y));
}
