// The light drawn behind the model as a sky dome: each pixel shows the SH light's radiance in
// the direction its view ray leaves, clamped at zero (src/render/sky.rs). Prepended by the
// page: #version and LIGHT_BANDS. The basis is `sh::eval_basis`: real, orthonormal, index
// l(l+1)+m, Condon-Shortley phase, associated Legendre functions by the normalised recurrence.
uniform vec3 light[LIGHT_BANDS * LIGHT_BANDS];   // all the light's coefficients, rotated
uniform vec3 camera_forward, camera_right, camera_up; // unit vectors
uniform vec2 half_extent;         // tan(fov / 2) * aspect, tan(fov / 2)
uniform vec2 viewport_size;       // pixels
out vec4 color;

vec3 sky_radiance(vec3 d) {
    const float SQRT_2 = 1.4142135623730951;
    vec3 sum = vec3(0.0);
    float cos_m = 1.0, sin_m = 0.0;          // Re, Im of (x + i y)^m
    float diag = sqrt(1.0 / (4.0 * 3.141592653589793)); // K_m^m P_m^m / sin^m
    for (int m = 0; m < LIGHT_BANDS; ++m) {
        if (m > 0) {
            diag *= -sqrt(float(2 * m + 1) / float(2 * m));
            float next_cos = d.x * cos_m - d.y * sin_m;
            sin_m = d.x * sin_m + d.y * cos_m;
            cos_m = next_cos;
        }
        float p_prev = 0.0, p = diag;
        for (int l = m; l < LIGHT_BANDS; ++l) {
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
                sum += light[centre] * p;
            } else {
                sum += light[centre + m] * (SQRT_2 * p * cos_m);
                sum += light[centre - m] * (SQRT_2 * p * sin_m);
            }
        }
    }
    return max(sum, 0.0);
}

void main() {
    vec2 ndc = gl_FragCoord.xy / viewport_size * 2.0 - 1.0;
    vec3 ray = normalize(camera_forward + ndc.x * half_extent.x * camera_right
                         + ndc.y * half_extent.y * camera_up);
    color = display_color(sky_radiance(ray));
}
