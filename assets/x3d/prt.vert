// PRT in an X3D browser: the transfer vector arrives as FloatVertexAttribute nodes (transfer0,
// transfer1, ...: the file's floats per vertex, channel-major, four to an attribute), the
// light as the ComposedShader's MFVec3f field `light`; exit radiance is their dot product per
// colour channel. Prepended by the exporter: #version, COEFFS (bands^2), CHANNELS (1 or 3),
// ATTRIBUTES, ALBEDO (the Color node's colour where the transfer is albedo-free, else 1) and
// TRANSFER_ARRAY (the attributes as one array).
uniform mat4 x3d_ProjectionMatrix;
uniform mat4 x3d_ModelViewMatrix;
uniform vec3 light[COEFFS];

in vec4 x3d_Vertex;
in vec4 x3d_Color;
TRANSFER_ATTRIBUTES
out vec3 radiance;

void main() {
    vec4 transfer[ATTRIBUTES] = TRANSFER_ARRAY;
    vec3 sum = vec3(0.0);
    for (int k = 0; k < COEFFS; ++k) {
#if CHANNELS == 3
        int g = COEFFS + k, b = 2 * COEFFS + k;
        vec3 t = vec3(transfer[k / 4][k % 4], transfer[g / 4][g % 4], transfer[b / 4][b % 4]);
#else
        vec3 t = vec3(transfer[k / 4][k % 4]);
#endif
        sum += light[k] * t;
    }
    radiance = sum * ALBEDO;
    gl_Position = x3d_ProjectionMatrix * x3d_ModelViewMatrix * x3d_Vertex;
}
