// Per-texel PRT: the lightmap coordinates are interpolated across the triangle, and the
// fragment shader relights the texels around them. bend.glsl places the vertex (the texels'
// transfer does not turn: that is what static PRT shows of a bent mesh).
uniform mat4 clip_from_world;

in vec3 position;
in vec2 texcoord;
out vec2 lightmap_uv;

void main() {
    lightmap_uv = texcoord;
    float turn;
    gl_Position = clip_from_world * vec4(bend(position, turn), 1.0);
}
