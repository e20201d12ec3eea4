// The light drawn behind the model as a sky dome: each pixel shows the SH light's radiance in
// the direction its view ray leaves, clamped at zero (src/render/sky.rs). Prepended by the
// page: tone-map and sh-sum, with SH_BANDS the light's bands; sh_coeffs holds all the light's
// coefficients, rotated.
uniform vec3 camera_forward, camera_right, camera_up; // unit vectors
uniform vec2 half_extent;         // tan(fov / 2) * aspect, tan(fov / 2)
uniform vec2 viewport_size;       // pixels
out vec4 color;

void main() {
    vec2 ndc = gl_FragCoord.xy / viewport_size * 2.0 - 1.0;
    vec3 ray = normalize(camera_forward + ndc.x * half_extent.x * camera_right
                         + ndc.y * half_extent.y * camera_up);
    color = display_color(max(sh_sum(ray), 0.0));
}
