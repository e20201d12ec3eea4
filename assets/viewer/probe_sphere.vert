// A diffuse test sphere lit by the probes at its centre, as `render --probe-sphere` draws it:
// each vertex's radiance is albedo / pi times the irradiance for its normal, the irradiance's
// SH (probes.js: the interpolated matrix times the light, convolved) summed in that direction.
// Prepended by the page: sh-sum, with SH_BANDS the probes' irradiance bands; sh_coeffs holds
// the irradiance's coefficients times albedo / pi.
uniform mat4 clip_from_world;
uniform vec3 centre;
uniform float radius;

in vec3 position;                     // on the unit sphere: also the normal
out vec3 radiance;

void main() {
    radiance = sh_sum(position);
    gl_Position = clip_from_world * vec4(centre + radius * position, 1.0);
}
