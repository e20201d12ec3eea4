// The whole run-time of PRT: a receiver's exit radiance is the dot product of its transfer
// vector with the light's SH coefficients, per colour channel. A receiver is a vertex
// (mesh.vert) or a lightmap texel (lightmap.frag). Prepended by the page: COEFFS (bands^2 of
// the bake), CHANNELS (1 or 3) and TRANSFER_WIDTH (texels per row of the transfer texture).
uniform vec3 light[COEFFS];           // the light's first COEFFS coefficients, rotated
uniform highp sampler2D transfer;     // texel receiver * COEFFS + k: coefficient k, per channel

vec3 transfer_coefficient(int receiver, int k) {
    int texel = receiver * COEFFS + k;
    vec4 t = texelFetch(transfer, ivec2(texel % TRANSFER_WIDTH, texel / TRANSFER_WIDTH), 0);
#if CHANNELS == 3
    return t.rgb;
#else
    return t.rrr;                     // one transfer for all three channels of the light
#endif
}

vec3 relight(int receiver) {
    vec3 sum = vec3(0.0);
    for (int k = 0; k < COEFFS; ++k) {
        sum += light[k] * transfer_coefficient(receiver, k);
    }
    return sum;
}
