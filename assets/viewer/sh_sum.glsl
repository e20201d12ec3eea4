// A function given by its SH coefficients, evaluated in a unit direction: the sky (sky.frag)
// and a probe-lit sphere's irradiance (probe_sphere.vert). Prepended by the page: SH_BANDS.
// The basis is `sh::eval_basis`: real, orthonormal, index l(l+1)+m, Condon-Shortley phase,
// associated Legendre functions by the normalised recurrence.
uniform vec3 sh_coeffs[SH_BANDS * SH_BANDS];

vec3 sh_sum(vec3 d) {
    const float SQRT_2 = 1.4142135623730951;
    vec3 sum = vec3(0.0);
    float cos_m = 1.0, sin_m = 0.0;          // Re, Im of (x + i y)^m
    float diag = sqrt(1.0 / (4.0 * 3.141592653589793)); // K_m^m P_m^m / sin^m
    for (int m = 0; m < SH_BANDS; ++m) {
        if (m > 0) {
            diag *= -sqrt(float(2 * m + 1) / float(2 * m));
            float next_cos = d.x * cos_m - d.y * sin_m;
            sin_m = d.x * sin_m + d.y * cos_m;
            cos_m = next_cos;
        }
        float p_prev = 0.0, p = diag;
        for (int l = m; l < SH_BANDS; ++l) {
            if (l == m + 1) {
                p_prev = p;
                p *= sqrt(float(2 * m + 3)) * d.z;
            } else if (l > m + 1) {
                float lf = float(l), mf = float(m);
                float a = sqrt((4.0 * lf * lf - 1.0) / (lf * lf - mf * mf));
                float b = sqrt(((lf - 1.0) * (lf - 1.0) - mf * mf) / (4.0 * (lf - 1.0) * (lf - 1.0) - 1.0));
                float next = a * (d.z * p - b * p_prev);
                p_prev = p;
                p = next;
            }
            int centre = l * (l + 1);
            if (m == 0) {
                sum += sh_coeffs[centre] * p;
            } else {
                sum += sh_coeffs[centre + m] * (SQRT_2 * p * cos_m);
                sum += sh_coeffs[centre - m] * (SQRT_2 * p * sin_m);
            }
        }
    }
    return sum;
}
