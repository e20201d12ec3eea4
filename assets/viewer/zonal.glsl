// LDPRT's run-time (`zonal::ZonalTransfer::relight`): a vertex's zonal lobe about its axis `a`
// under the light gives sum_l z_l sqrt(4 pi / (2l+1)) sum_m light_lm y_lm(a); the basis by the
// recurrence of sh_sum.glsl, summed band by band. Prepended by the page: COEFFS (the light's
// coefficients, at least ZONAL_BANDS^2), ZONAL_BANDS, CHANNELS and TRANSFER_WIDTH.
uniform vec3 light[COEFFS];           // the light's first COEFFS coefficients, rotated
uniform highp sampler2D zonal;        // texel vertex * ZONAL_BANDS + l: band l, per channel

vec3 zonal_coefficient(int receiver, int l) {
    int texel = receiver * ZONAL_BANDS + l;
    vec4 z = texelFetch(zonal, ivec2(texel % TRANSFER_WIDTH, texel / TRANSFER_WIDTH), 0);
#if CHANNELS == 3
    return z.rgb;
#else
    return z.rrr;
#endif
}

vec3 relight_zonal(int receiver, vec3 a) {
    const float PI = 3.141592653589793;
    const float SQRT_2 = 1.4142135623730951;
    vec3 band[ZONAL_BANDS];                  // sum_m light_lm y_lm(a), per band
    for (int l = 0; l < ZONAL_BANDS; ++l) band[l] = vec3(0.0);
    float cos_m = 1.0, sin_m = 0.0;          // Re, Im of (x + i y)^m
    float diag = sqrt(1.0 / (4.0 * PI));     // K_m^m P_m^m / sin^m
    for (int m = 0; m < ZONAL_BANDS; ++m) {
        if (m > 0) {
            diag *= -sqrt(float(2 * m + 1) / float(2 * m));
            float next_cos = a.x * cos_m - a.y * sin_m;
            sin_m = a.x * sin_m + a.y * cos_m;
            cos_m = next_cos;
        }
        float p_prev = 0.0, p = diag;
        for (int l = m; l < ZONAL_BANDS; ++l) {
            if (l == m + 1) {
                p_prev = p;
                p *= sqrt(float(2 * m + 3)) * a.z;
            } else if (l > m + 1) {
                float lf = float(l), mf = float(m);
                float c = sqrt((4.0 * lf * lf - 1.0) / (lf * lf - mf * mf));
                float d = sqrt(((lf - 1.0) * (lf - 1.0) - mf * mf) / (4.0 * (lf - 1.0) * (lf - 1.0) - 1.0));
                float next = c * (a.z * p - d * p_prev);
                p_prev = p;
                p = next;
            }
            int centre = l * (l + 1);
            if (m == 0) {
                band[l] += light[centre] * p;
            } else {
                band[l] += light[centre + m] * (SQRT_2 * p * cos_m) + light[centre - m] * (SQRT_2 * p * sin_m);
            }
        }
    }
    vec3 sum = vec3(0.0);
    for (int l = 0; l < ZONAL_BANDS; ++l) {
        sum += zonal_coefficient(receiver, l) * (sqrt(4.0 * PI / float(2 * l + 1)) * band[l]);
    }
    return sum;
}
