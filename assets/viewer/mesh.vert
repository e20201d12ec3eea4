// Per-vertex PRT: each vertex relit (transfer.glsl; with ZONAL_BANDS, zonal.glsl about its
// axis turned by the bend), times the albedo where the file keeps it out of the transfer; the
// radiance is interpolated across the triangle. bend.glsl places the vertex.
uniform mat4 clip_from_world;

in vec3 position;
in vec3 albedo;                       // (1, 1, 1) unless the transfer is albedo-free
#ifdef ZONAL_BANDS
in vec3 axis;                         // the zonal lobe's axis in the rest pose
#endif
out vec3 radiance;

void main() {
    float turn;
    vec3 placed = bend(position, turn);
#ifdef ZONAL_BANDS
    radiance = relight_zonal(gl_VertexID, turned(axis, turn)) * albedo;
#else
    radiance = relight(gl_VertexID) * albedo;
#endif
    gl_Position = clip_from_world * vec4(placed, 1.0);
}
