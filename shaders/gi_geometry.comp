#version 450
// Dynamic GI stage 1: the geometry volume, one invocation per triangle. CPU twin:
// buildGiGeometry (runtime/src/gi_geometry.cpp) with sampleTriangleInBox (formats/
// triangle_sampling.hpp): the triangle clipped to the geometry volume's box (Sutherland-Hodgman),
// fanned, each fan triangle split into m^2 sub-triangles whose centroids carry their area. Every
// sample's contribution is rounded to fixed point before the atomic add, so the sums do not
// depend on the order the invocations run in; the buffer is cleared before the dispatch.
// info.z: triangle count, info.w: vertex count.
#extension GL_GOOGLE_include_directive : require
#define PK_GI_STAGE
#include "gi_common.glsl"

layout(local_size_x = 64) in;

// RenderVertex, 14 tightly packed floats: position, normal, albedo, emission, uv.
layout(std430, set = 0, binding = 1) readonly buffer PkGiVertices {
    float vertices[];
};
layout(std430, set = 0, binding = 2) readonly buffer PkGiIndices {
    uint indices[];
};
layout(std430, set = 0, binding = 3) buffer PkGiGeometryVolume {
    int geometry[];
};

const float PK_GI_LAMBDA0 = 4.18879032; // float(4/3) x float(pi), as gi_geometry.cpp
const float PK_GI_LAMBDA2 = 1.67551625; // float(8/15) x float(pi)
const int PK_GI_MAX_POLYGON = 10;       // a triangle clipped by six planes has at most 9 corners

vec3 vertexPosition(uint v) {
    return vec3(vertices[14u * v], vertices[14u * v + 1u], vertices[14u * v + 2u]);
}
vec3 vertexAlbedo(uint v) {
    return vec3(vertices[14u * v + 6u], vertices[14u * v + 7u], vertices[14u * v + 8u]);
}

// giCanonicalNormal: the side whose largest-magnitude component is positive; `front` when that
// is n itself (the twin's normal == cross / length).
vec3 canonicalNormal(vec3 n, out bool front) {
    const vec3 a = abs(n);
    const int axis = a.x >= a.y && a.x >= a.z ? 0 : (a.y >= a.z ? 1 : 2);
    front = !(n[axis] < 0.0);
    return front ? n : -n;
}

float g_perUnitArea[6];
vec3 g_normal;
bool g_front;
vec3 g_albedo;

void emitSample(vec3 p, float area) {
    const float s = pk_gi_push.originCellSize.w;
    const vec3 origin = pk_gi_push.originCellSize.xyz;
    const int gv = pk_gi_push.info.x + 1;
    const ivec3 g = clamp(ivec3(floor((p - origin) / s + 0.5)), ivec3(0), ivec3(gv - 1));
    const int base = PK_GI_GEOMETRY_INTS * (g.x + gv * (g.y + gv * g.z));
    for (int k = 0; k < 6; ++k) {
        atomicAdd(geometry[base + k], pk_gi_fixed(area * g_perUnitArea[k]));
    }
    const float per_area = 1.0 / (s * s);
    const float inv_s = 1.0 / s;
    const float a = area * per_area;
    const vec3 offset = (p - origin) * inv_s - vec3(g);
    atomicAdd(geometry[base + 6], pk_gi_fixed(a));
    for (int ch = 0; ch < 3; ++ch) {
        atomicAdd(geometry[base + 7 + ch], pk_gi_fixed(a * g_albedo[ch]));
        atomicAdd(geometry[base + 10 + ch], pk_gi_fixed(a * g_normal[ch]));
        atomicAdd(geometry[base + 13 + ch], pk_gi_fixed(a * offset[ch]));
    }
    if (g_front) {
        atomicAdd(geometry[base + 16], pk_gi_fixed(a));
    }
}

void main() {
    const uint t = gl_GlobalInvocationID.x;
    if (t >= uint(pk_gi_push.info.z)) {
        return;
    }
    const uint vertex_count = uint(pk_gi_push.info.w);
    const uint ia = indices[3u * t];
    const uint ib = indices[3u * t + 1u];
    const uint ic = indices[3u * t + 2u];
    if (ia >= vertex_count || ib >= vertex_count || ic >= vertex_count) {
        return;
    }
    const vec3 a = vertexPosition(ia);
    const vec3 b = vertexPosition(ib);
    const vec3 c = vertexPosition(ic);
    const vec3 cr = cross(b - a, c - a);
    const float len = length(cr);
    if (!(len > 0.0)) {
        return;
    }
    const float s = pk_gi_push.originCellSize.w;
    g_normal = canonicalNormal(cr / len, g_front);
    float y[6];
    pk_gi_blocking_basis(cr / len, y);
    const float per_area = 1.0 / (s * s);
    for (int k = 0; k < 6; ++k) {
        g_perUnitArea[k] = per_area * (k == 0 ? PK_GI_LAMBDA0 : PK_GI_LAMBDA2) * y[k];
    }
    g_albedo = (vertexAlbedo(ia) + vertexAlbedo(ib) + vertexAlbedo(ic)) / 3.0;

    // sampleTriangleInBox.
    const vec3 origin = pk_gi_push.originCellSize.xyz;
    const vec3 box_min = origin - 0.5 * s;
    const vec3 box_max = origin + (float(pk_gi_push.info.x) + 0.5) * s;
    vec3 polygon[PK_GI_MAX_POLYGON];
    vec3 clipped[PK_GI_MAX_POLYGON];
    polygon[0] = a;
    polygon[1] = b;
    polygon[2] = c;
    int size = 3;
    for (int axis = 0; axis < 3; ++axis) {
        for (int side = 0; side < 2; ++side) {
            const float bound = side == 0 ? box_min[axis] : box_max[axis];
            const float sign = side == 0 ? 1.0 : -1.0;
            int out_size = 0;
            for (int i = 0; i < size; ++i) {
                const vec3 p = polygon[i];
                const vec3 q = polygon[(i + 1) % size];
                const float dp = sign * (p[axis] - bound);
                const float dq = sign * (q[axis] - bound);
                if (dp >= 0.0 && out_size < PK_GI_MAX_POLYGON) {
                    clipped[out_size++] = p;
                }
                if ((dp >= 0.0) != (dq >= 0.0) && out_size < PK_GI_MAX_POLYGON) {
                    clipped[out_size++] = p + (q - p) * (dp / (dp - dq));
                }
            }
            for (int i = 0; i < out_size; ++i) {
                polygon[i] = clipped[i];
            }
            size = out_size;
            if (size < 3) {
                return;
            }
        }
    }
    const float max_edge = 0.5 * s;
    for (int k = 1; k + 1 < size; ++k) {
        const vec3 p0 = polygon[0];
        const vec3 e1 = polygon[k] - p0;
        const vec3 e2 = polygon[k + 1] - p0;
        const float area = 0.5 * length(cross(e1, e2));
        if (!(area > 0.0)) {
            continue;
        }
        const float longest = max(max(length(e1), length(e2)), length(e2 - e1));
        const int m = max(1, int(ceil(longest / max_edge)));
        const float sub_area = area / float(m * m);
        const float inv_m = 1.0 / float(m);
        for (int i = 0; i < m; ++i) {
            for (int j = 0; i + j < m; ++j) {
                const float fi = float(i);
                const float fj = float(j);
                emitSample(p0 + ((fi + 1.0 / 3.0) * e1 + (fj + 1.0 / 3.0) * e2) * inv_m, sub_area);
                if (i + j + 1 < m) {
                    emitSample(p0 + ((fi + 2.0 / 3.0) * e1 + (fj + 2.0 / 3.0) * e2) * inv_m,
                               sub_area);
                }
            }
        }
    }
}
