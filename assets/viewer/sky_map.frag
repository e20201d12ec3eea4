// The environment map itself behind the model as a sky dome: each pixel shows the map's
// lat-long copy (src/light/sky.rs) looked up bilinearly along its view ray, turned back by the
// light's rotation so that sky and shading turn together. The lat-long layout is
// `light::mapping`'s: azimuth atan2(z, x) from -pi at the left edge, elevation asin(y) from
// +pi/2 at the top row. The texture repeats horizontally and clamps vertically.
uniform sampler2D sky_map;
uniform mat3 map_from_world;      // the inverse (transpose) of the light's rotation
uniform vec3 camera_forward, camera_right, camera_up; // unit vectors
uniform vec2 half_extent;         // tan(fov / 2) * aspect, tan(fov / 2)
uniform vec2 viewport_size;       // pixels
out vec4 color;

void main() {
    const float PI = 3.141592653589793;
    vec2 ndc = gl_FragCoord.xy / viewport_size * 2.0 - 1.0;
    vec3 ray = normalize(camera_forward + ndc.x * half_extent.x * camera_right
                         + ndc.y * half_extent.y * camera_up);
    vec3 d = normalize(map_from_world * ray);
    float azimuth = atan(d.z, d.x);
    float elevation = asin(clamp(d.y, -1.0, 1.0));
    vec2 uv = vec2(azimuth / (2.0 * PI) + 0.5, 0.5 - elevation / PI);
    color = display_color(max(texture(sky_map, uv).rgb, 0.0));
}
