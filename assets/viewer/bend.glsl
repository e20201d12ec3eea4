// The bend of `zonal::Bend` (render --bend): height above the mesh's lowest point turns by
// bend_angle * y / bend_height about a line parallel to +Z, bend_height / bend_angle beside the
// mesh's middle; a bend_angle of 0 leaves the mesh as baked.
uniform float bend_angle;             // the top's turn, radians
uniform vec3 bend_origin;             // the mesh's middle in x at its lowest y
uniform float bend_height;

vec3 bend(vec3 position, out float turn) {
    turn = 0.0;
    if (bend_angle == 0.0 || bend_height <= 0.0) return position;
    vec3 local = position - bend_origin;
    float radius = bend_height / bend_angle;
    turn = local.y / radius;
    float arm = radius - local.x;
    return bend_origin + vec3(radius - arm * cos(turn), arm * sin(turn), local.z);
}

// `v` turned with the surface where the bend turned it by `turn`: clockwise about +Z.
vec3 turned(vec3 v, float turn) {
    float c = cos(turn), s = sin(turn);
    return vec3(c * v.x + s * v.y, -s * v.x + c * v.y, v.z);
}
