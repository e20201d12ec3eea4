// Per-vertex PRT: each vertex relit (transfer.glsl), times the albedo where the file keeps it
// out of the transfer; the radiance is interpolated across the triangle.
uniform mat4 clip_from_world;

in vec3 position;
in vec3 albedo;                       // (1, 1, 1) unless the transfer is albedo-free
out vec3 radiance;

void main() {
    radiance = relight(gl_VertexID) * albedo;
    gl_Position = clip_from_world * vec4(position, 1.0);
}
