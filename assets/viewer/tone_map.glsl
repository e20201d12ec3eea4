// Exposure, tone mapping and sRGB encoding, per pixel on linear radiance: the same functions
// as `prt-gpu render` (src/render/image.rs `tone_map`, src/color.rs `srgb_encode`), so a
// screenshot of the page matches its PNG.
uniform float exposure_stops;
uniform int tone_map_kind; // 0 none, 1 Reinhard, 2 ACES (Narkowicz's fit)

float tone_map(float value) {
    float x = max(value * exp2(exposure_stops), 0.0);
    float mapped = x;
    if (tone_map_kind == 1) {
        mapped = x / (1.0 + x);
    } else if (tone_map_kind == 2) {
        mapped = (x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14);
    }
    return clamp(mapped, 0.0, 1.0);
}

float srgb_encode(float linear) {
    return linear <= 0.0031308 ? 12.92 * linear : 1.055 * pow(linear, 1.0 / 2.4) - 0.055;
}

vec4 display_color(vec3 radiance) {
    return vec4(srgb_encode(tone_map(radiance.r)), srgb_encode(tone_map(radiance.g)),
                srgb_encode(tone_map(radiance.b)), 1.0);
}
