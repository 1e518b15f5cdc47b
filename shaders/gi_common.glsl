// Dynamic GI (runtime/include/probekit/runtime/dynamic_gi.hpp): what the gi_*.comp stages and
// the shading pass share. Every function mirrors its CPU twin in runtime/src/gi_geometry.cpp or
// runtime/src/gi_twin.cpp term for term (the same constants, rounded to float as the C++ rounds
// them, and the same order of operations), so that the GPU tests can hold the shaders to the
// twin.
//
// Use from another shader (e.g. shade.comp for the sun's visibility):
//   #define PK_GI_GEOMETRY(i) my_geometry_block.cells[i] // int i -> int, the geometry volume
//   #include "gi_common.glsl"
// The geometry functions (pk_gi_cell_potential, pk_gi_face_potential, pk_gi_transmittance) are
// compiled only when PK_GI_GEOMETRY is defined; the geometry volume is 17 int32 per geometry
// cell (gi_geometry.hpp's GiGeometryCell: blocking[6], area, albedoArea[3], normalArea[3],
// offsetArea[3], frontArea), (cells + 1)^3 cells, x fastest. The cascade is passed as a PkGiLayout.
// PK_GI_STAGE (defined by the gi_*.comp stages only) adds the stages' push constants.
#ifndef PK_GI_COMMON_GLSL
#define PK_GI_COMMON_GLSL

// formats/sh.hpp's constants, as float.
const float PK_GI_Y00 = 0.282095;
const float PK_GI_Y1 = 0.488603;
const float PK_GI_Y2 = 1.092548;
const float PK_GI_Y20 = 0.315392;
const float PK_GI_Y22 = 0.546274;
const float PK_GI_PI = 3.14159274;
// sh::kCosineLobe[0..1].
const float PK_GI_A0 = 3.14159274;
const float PK_GI_A1 = 2.09439516;
// float(sqrt(4 pi)) (gi_twin.cpp kSqrtFourPi).
const float PK_GI_SQRT_FOUR_PI = 3.54490781;
// int32 per geometry cell (GiGeometryCell).
const int PK_GI_CELL_INTS = 17;
// Fixed-point unit of the geometry sums (gi_geometry.hpp kGiFixedScale).
const float PK_GI_FIXED_SCALE = 65536.0;
// int32 per geometry cell (gi_geometry.hpp GiGeometryCell: blocking[6], area, albedoArea[3],
// normalArea[3], offsetArea[3], frontArea).
#define PK_GI_GEOMETRY_INTS 17
// The resolve's band factors, 1 / (6 A0 Y00) and 1 / (2 A1 Y1), as the twin's float arithmetic
// gives them.
const float PK_GI_RESOLVE_BAND0 = 0.18806307;
const float PK_GI_RESOLVE_BAND1 = 0.488602042;

// The twin's fixedPoint: rounded in float.
int pk_gi_fixed(float value) {
    return int(floor(value * PK_GI_FIXED_SCALE + 0.5));
}

// L1 real SH basis at unit w: (Y00, Y1-1, Y10, Y11) = (Y00, Y1 y, Y1 z, Y1 x).
vec4 pk_gi_basis_l1(vec3 w) {
    return vec4(PK_GI_Y00, PK_GI_Y1 * w.y, PK_GI_Y1 * w.z, PK_GI_Y1 * w.x);
}

// The blocking's six basis functions at unit w: Y00, then Y2-2..Y22 (sh::evalBasis 0, 4..8).
void pk_gi_blocking_basis(vec3 w, out float y[6]) {
    y[0] = PK_GI_Y00;
    y[1] = PK_GI_Y2 * w.x * w.y;
    y[2] = PK_GI_Y2 * w.y * w.z;
    y[3] = PK_GI_Y20 * (3.0 * w.z * w.z - 1.0);
    y[4] = PK_GI_Y2 * w.x * w.z;
    y[5] = PK_GI_Y22 * (w.x * w.x - w.y * w.y);
}

// A cascade: world min corner, cell size (metres) and LPV cells per axis; its geometry volume
// has cells + 1 per axis, offset by half a cell.
struct PkGiLayout {
    vec3 origin;
    float cellSize;
    int cells;
};

bool pk_gi_inside(ivec3 c, int n) {
    return all(greaterThanEqual(c, ivec3(0))) && all(lessThan(c, ivec3(n)));
}
int pk_gi_cell_index(ivec3 c, int n) {
    return c.x + n * (c.y + n * c.z);
}
ivec3 pk_gi_cell_of_index(int i, int n) {
    return ivec3(i % n, (i / n) % n, i / (n * n));
}

// Axis directions d = 0..5: +x, -x, +y, -y, +z, -z.
ivec3 pk_gi_direction(int d) {
    ivec3 v = ivec3(0);
    v[d / 2] = (d & 1) == 0 ? 1 : -1;
    return v;
}

// The five faces a transfer towards neighbour d reaches (gi_twin.cpp makeFaces): f = 0 the far
// face (along d, solid angle 4 asin(0.1)), f = 1..4 the side faces in axis order, +0.5 before
// -0.5, along normalize(d + 0.5 e) (solid angle (4 pi / 6 - far) / 4). The numbers are the
// twin's double-precision table rounded to float.
const float PK_GI_FAR_SOLID_ANGLE = 0.400669694;
const float PK_GI_SIDE_SOLID_ANGLE = 0.423431367;
const float PK_GI_SIDE_MAIN = 0.89442718;  // 1 / sqrt(1.25)
const float PK_GI_SIDE_OTHER = 0.44721359; // 0.5 / sqrt(1.25)
vec3 pk_gi_face_direction(int d, int f) {
    const vec3 main = vec3(pk_gi_direction(d));
    if (f == 0) {
        return main;
    }
    const int axis = d / 2;
    const int other = (f <= 2) ? (axis == 0 ? 1 : 0) : (axis == 2 ? 1 : 2);
    vec3 w = main * PK_GI_SIDE_MAIN;
    w[other] = (f & 1) == 1 ? PK_GI_SIDE_OTHER : -PK_GI_SIDE_OTHER;
    return w;
}
float pk_gi_face_solid_angle(int f) {
    return f == 0 ? PK_GI_FAR_SOLID_ANGLE : PK_GI_SIDE_SOLID_ANGLE;
}

#ifdef PK_GI_GEOMETRY
int pk_gi_geometry_index(ivec3 g, int gv) {
    return g.x + gv * (g.y + gv * g.z);
}

// Bands 0 and 2 of the geometry cell's blocking at unit w, unclamped (giCellPotential).
float pk_gi_cell_potential(int geometry_cell, vec3 w) {
    float y[6];
    pk_gi_blocking_basis(w, y);
    float potential = 0.0;
    for (int k = 0; k < 6; ++k) {
        potential += float(PK_GI_GEOMETRY(PK_GI_GEOMETRY_INTS * geometry_cell + k)) / PK_GI_FIXED_SCALE * y[k];
    }
    return potential;
}

// The blocking at w averaged over the four geometry cells at the corners of the face between
// LPV cell `cell` and its neighbour along d, unclamped (giFacePotential).
float pk_gi_face_potential(PkGiLayout cascade, ivec3 cell, int d, vec3 w) {
    const int axis = d / 2;
    ivec3 g0 = cell;
    g0[axis] += (d & 1) == 0 ? 1 : 0;
    const int u = (axis + 1) % 3;
    const int v = (axis + 2) % 3;
    float y[6];
    pk_gi_blocking_basis(w, y);
    const int gv = cascade.cells + 1;
    float potential = 0.0;
    for (int corner = 0; corner < 4; ++corner) {
        ivec3 g = g0;
        g[u] += corner & 1;
        g[v] += corner >> 1;
        if (!pk_gi_inside(g, gv)) {
            continue;
        }
        const int base = PK_GI_GEOMETRY_INTS * pk_gi_geometry_index(g, gv);
        for (int k = 0; k < 6; ++k) {
            potential += 0.25 * float(PK_GI_GEOMETRY(base + k)) / PK_GI_FIXED_SCALE * y[k];
        }
    }
    return potential;
}

// Fraction of light from `from` along unit `direction` that reaches `distance` metres (+inf,
// e.g. uintBitsToFloat(0x7f800000u), for a directional light) through the geometry volume:
// steps of one cell while inside the volume and k s < distance, each step's nearest geometry
// cell (skipping `skip` and the previous step's cell) multiplying by 1 - clamp(B(direction), 0,
// 1) (giTransmittance). Pass skip = ivec3(-1) to skip nothing.
float pk_gi_transmittance(PkGiLayout cascade, vec3 from, vec3 direction, float distance,
                          ivec3 skip) {
    const float s = cascade.cellSize;
    const int gv = cascade.cells + 1;
    float transmittance = 1.0;
    ivec3 previous = skip;
    // The march leaves the volume within sqrt(3) gv steps; the cap only guards against NaN.
    const int max_steps = 2 * gv + 2;
    for (int k = 1; k <= max_steps && float(k) * s < distance; ++k) {
        const vec3 p = from + direction * (s * float(k));
        const ivec3 g = ivec3(floor((p - cascade.origin) / s + 0.5));
        if (!pk_gi_inside(g, gv)) {
            break;
        }
        if (g == skip || g == previous) {
            continue;
        }
        previous = g;
        const float b = pk_gi_cell_potential(pk_gi_geometry_index(g, gv), direction);
        transmittance *= 1.0 - clamp(b, 0.0, 1.0);
        if (transmittance <= 0.0) {
            break;
        }
    }
    return transmittance;
}
#endif // PK_GI_GEOMETRY

#ifdef PK_GI_STAGE
// Per-dispatch constants of the gi_*.comp stages (DynamicGi's GiPush, runtime/src/
// dynamic_gi.cpp).
layout(push_constant) uniform PkGiPush {
    vec4 originCellSize; // cascade origin (xyz), cell size (w)
    ivec4 info;          // x: cells per axis, y: stage flag (see each stage), z, w: counts
    vec4 extra;          // x: propagation weight
}
pk_gi_push;

PkGiLayout pk_gi_layout() {
    PkGiLayout cascade;
    cascade.origin = pk_gi_push.originCellSize.xyz;
    cascade.cellSize = pk_gi_push.originCellSize.w;
    cascade.cells = pk_gi_push.info.x;
    return cascade;
}
#endif // PK_GI_STAGE

#endif // PK_GI_COMMON_GLSL
