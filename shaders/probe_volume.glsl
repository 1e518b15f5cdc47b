// probekit probe volumes in GLSL. Conventions: formats/CONVENTIONS.md (radiance SH, real
// orthonormal Ramamoorthi-Hanrahan basis, no Condon-Shortley phase, glTF axes; irradiance E in
// W/m^2, not divided by pi).
//
// Texel planes (formats/include/probekit/formats/volume.hpp): plane c (0..2) holds
// (L00, L1-1, L10, L11) of channel c; planes 3..6 hold the 15 band-2 values, value j = 3k + c at
// plane 3 + j / 4, component j % 4.
#ifndef PROBEKIT_PROBE_VOLUME_GLSL
#define PROBEKIT_PROBE_VOLUME_GLSL

const float PK_PI = 3.14159265358979323846;

// Irradiance from unpacked RGB coefficients sh[0..8] (sh[4..8] zero for L1) at unit normal n.
// Mirrors probekit::sh::irradiance (formats/src/sh.cpp) term for term:
// E(n) = sum_lm A_l L_lm Y_lm(n), A = (pi, 2pi/3, pi/4).
vec3 pk_sh_irradiance(vec3 sh[9], vec3 n) {
    const float a0 = PK_PI;
    const float a1 = 2.0 * PK_PI / 3.0;
    const float a2 = PK_PI / 4.0;
    vec3 e = a0 * 0.282095 * sh[0];
    e += a1 * 0.488603 * (sh[1] * n.y + sh[2] * n.z + sh[3] * n.x);
    e += a2 * (1.092548 * (sh[4] * (n.x * n.y) + sh[5] * (n.y * n.z) + sh[7] * (n.x * n.z)) +
               0.315392 * sh[6] * (3.0 * n.z * n.z - 1.0) +
               0.546274 * sh[8] * (n.x * n.x - n.y * n.y));
    return e;
}

// Unpacks the 7 (or, for L1, the first 3) RGBA texels of one probe into RGB coefficients.
// Mirrors probekit::unpackProbe (formats/src/volume.cpp).
void pk_unpack_probe(vec4 t[7], bool l2, out vec3 sh[9]) {
    for (int i = 0; i < 4; ++i) {
        sh[i] = vec3(t[0][i], t[1][i], t[2][i]);
    }
    for (int k = 0; k < 5; ++k) {
        vec3 c = vec3(0.0);
        if (l2) {
            for (int ch = 0; ch < 3; ++ch) {
                int j = 3 * k + ch;
                c[ch] = t[3 + j / 4][j % 4];
            }
        }
        sh[4 + k] = c;
    }
}

#endif
