// Per-texel PRT: the lightmap coordinates are interpolated across the triangle, and the
// fragment shader relights the texels around them.
uniform mat4 clip_from_world;

in vec3 position;
in vec2 texcoord;
out vec2 lightmap_uv;

void main() {
    lightmap_uv = texcoord;
    gl_Position = clip_from_world * vec4(position, 1.0);
}
