// The whole run-time of PRT: exit radiance is the dot product of the vertex's transfer vector
// with the light's SH coefficients, per colour channel (times the albedo where the file keeps
// it out of the transfer). Prepended by the page: #version, COEFFS (bands^2 of the bake),
// CHANNELS (1 or 3) and TRANSFER_WIDTH (texels per row of the transfer texture).
uniform mat4 clip_from_world;
uniform vec3 light[COEFFS];           // the light's first COEFFS coefficients, rotated
uniform highp sampler2D transfer;     // texel vertex * COEFFS + k: coefficient k, one per channel

in vec3 position;
in vec3 albedo;                       // (1, 1, 1) unless the transfer is albedo-free
out vec3 radiance;

vec3 transfer_coefficient(int vertex, int k) {
    int texel = vertex * COEFFS + k;
    vec4 t = texelFetch(transfer, ivec2(texel % TRANSFER_WIDTH, texel / TRANSFER_WIDTH), 0);
#if CHANNELS == 3
    return t.rgb;
#else
    return t.rrr;                     // one transfer for all three channels of the light
#endif
}

void main() {
    vec3 sum = vec3(0.0);
    for (int k = 0; k < COEFFS; ++k) {
        sum += light[k] * transfer_coefficient(gl_VertexID, k);
    }
    radiance = sum * albedo;
    gl_Position = clip_from_world * vec4(position, 1.0);
}
