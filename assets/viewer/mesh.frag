// Radiance interpolated across the triangle (as `prt-gpu render` does), then tone mapped.
in vec3 radiance;
out vec4 color;

void main() {
    color = display_color(radiance);
}
