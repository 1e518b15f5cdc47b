/* probekit_pvol.h -- a dependency-free C99 reader of probekit's .pvol files (baked light-probe
 * volumes), as a single header.
 *
 * Use: in exactly one C or C++ file of the program,
 *
 *     #define PROBEKIT_PVOL_IMPLEMENTATION
 *     #include "probekit_pvol.h"
 *
 * and include it without the define everywhere else. It needs only the C standard library
 * (<math.h>'s sqrtf: link libm where the platform keeps it apart, -lm on Linux).
 *
 * Allocation goes through PKV_MALLOC(size) and PKV_FREE(pointer), malloc and free unless both
 * are defined before the implementation is included.
 *
 * What it reads is the byte layout documented in formats/include/probekit/formats/pvol.hpp,
 * and it accepts exactly the files probekit's own decoder (decodePvol, formats/src/pvol.cpp)
 * accepts: the header (magic, version 1 or 2, header size, payload size equal to what follows),
 * the xxHash64 of the payload, then every field of the payload. Every count is checked against
 * the bytes that remain before anything is allocated, every enum against its known values,
 * every float field for finiteness, the parameters' JSON for nesting at most 64 levels deep,
 * every resolution for a power of two in 1..256, the brick list for a complete tiling,
 * validity bytes for 0 or 1, and every texel for a finite value of magnitude at most 1e30. A rejected file yields a status code and a message naming the volume
 * and the field. The file's own text (names, metadata) is kept as its bytes: escape it before
 * printing it to a terminal. The messages escape the volume name themselves.
 *
 * The data model (formats/include/probekit/formats/volume.hpp, grid.hpp, brick.hpp,
 * visibility.hpp; units and SH basis in formats/CONVENTIONS.md):
 *  - a volume is an axis-aligned box [bounds_min, bounds_max] in its local frame (metres, glTF
 *    axes, +Y up), placed in the world by world = rotation * local + translation;
 *  - dense: resolution[0] * resolution[1] * resolution[2] probes, x fastest; centre mode puts
 *    probe i at min + (i + 0.5) * size / res, corner mode at min + i * size / (res - 1);
 *  - bricked: resolution counts level-0 bricks; each brick holds 4 x 4 x 4 probes (probe k of
 *    brick b is stored as probe 64 b + k, k = x + 4 (y + 4 z)) over its region at its level
 *    (0..max_level, each level 2x finer); `indirection` maps every finest cell (x fastest) to
 *    the brick shown there;
 *  - coefficients are radiance SH, Ramamoorthi-Hanrahan order (Y00, Y1-1, Y10, Y11, Y2-2, Y2-1,
 *    Y20, Y21, Y22), stored as RGBA texel planes (3 for L1, 7 for L2), plane-major: component
 *    k of plane p at probe i is element 4 (p * probe_count + i) + k; pkv_probe_sh unpacks them;
 *  - validity: one byte per probe, 1 = valid, 0 = inside geometry (filled from neighbours);
 *  - visibility (optional): 6 bytes per probe, half-axes +x, -x, +y, -y, +z, -z, the distance
 *    to the first surface in units of the probe spacing, quantised to 0..255.
 */
#ifndef PROBEKIT_PVOL_H
#define PROBEKIT_PVOL_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Outcome of pkv_open_memory. The failure kinds are probekit's ErrorCode values
 * (formats/include/probekit/formats/result.hpp), plus PKV_ERROR_OUT_OF_MEMORY. */
typedef enum pkv_status {
    PKV_OK = 0,
    PKV_ERROR_BAD_MAGIC,           /* not a .pvol file */
    PKV_ERROR_UNSUPPORTED_VERSION, /* a format version this reader does not know */
    PKV_ERROR_TRUNCATED,           /* fewer bytes than the header or a field promises */
    PKV_ERROR_TRAILING_BYTES,      /* bytes after the end of the payload */
    PKV_ERROR_CHECKSUM_MISMATCH,   /* the payload does not hash to the stored xxHash64 */
    PKV_ERROR_INCONSISTENT_SIZE,   /* a count disagrees with another field, bricks do not tile */
    PKV_ERROR_BAD_RESOLUTION,      /* a resolution outside 1..256 or not a power of two */
    PKV_ERROR_NON_FINITE,          /* NaN or infinity where a finite number is required */
    PKV_ERROR_OUT_OF_RANGE,        /* a finite value outside its field's range */
    PKV_ERROR_BAD_ENUM,            /* an enum field holds an unknown value */
    PKV_ERROR_INVALID_ARGUMENT,    /* a null pointer passed to pkv_open_memory */
    PKV_ERROR_OUT_OF_MEMORY        /* PKV_MALLOC returned NULL */
} pkv_status;

typedef enum pkv_layout { PKV_LAYOUT_DENSE = 0, PKV_LAYOUT_BRICKED = 1 } pkv_layout;
typedef enum pkv_position_mode {
    PKV_POSITION_CENTER = 0,
    PKV_POSITION_CORNER = 1
} pkv_position_mode;
typedef enum pkv_storage { PKV_STORAGE_FLOAT = 0, PKV_STORAGE_HALF = 1 } pkv_storage;

/* The file's bytes, with a terminating NUL added (the bytes themselves may hold NULs). */
typedef struct pkv_string {
    const char* data;
    size_t size;
} pkv_string;

typedef struct pkv_metadata {
    pkv_string tool_version;    /* e.g. "probekit 0.1.0" */
    pkv_string method;          /* "path", "vpl", "lpv", "synthetic", ... */
    pkv_string parameters_json; /* the bake's settings, a JSON object as text */
    uint64_t seed;
    uint64_t scene_hash; /* xxHash64 of the scene file (0 when there was none) */
    double bake_seconds; /* 0 in files probekit writes now */
} pkv_metadata;

typedef struct pkv_brick {
    uint32_t coord[3]; /* region index at its level, < resolution * 2^level per axis */
    uint32_t level;    /* 0..max_level */
} pkv_brick;

typedef struct pkv_volume {
    pkv_string name;
    pkv_layout layout;
    float bounds_min[3]; /* local frame, metres; bounds_max > bounds_min on every axis */
    float bounds_max[3];
    uint32_t resolution[3];          /* dense: probes per axis; bricked: level-0 bricks */
    pkv_position_mode position_mode; /* always centre for bricked volumes */
    float rotation[4];               /* unit quaternion, (w, x, y, z) */
    float translation[3];
    uint32_t sh_order;          /* 1 (L1) or 2 (L2) */
    uint32_t coefficient_count; /* 4 (L1) or 9 (L2) */
    uint32_t plane_count;       /* 3 (L1) or 7 (L2) */
    pkv_storage storage;
    int32_t blend_priority; /* higher wins where volumes overlap */
    float fade_distance;    /* metres inside the border over which the volume fades out */

    /* Bricked only (zero and NULL for dense volumes). */
    uint32_t max_level; /* 0..3 */
    size_t brick_count;
    pkv_brick* bricks;
    uint32_t finest_cells[3]; /* resolution * 2^max_level */
    uint32_t* indirection;    /* finest_cells[0] * [1] * [2] brick indices, x fastest */

    size_t probe_count;  /* dense: the grid's probes; bricked: 64 * brick_count */
    uint8_t* validity;   /* probe_count bytes, each 0 or 1 */
    uint8_t* visibility; /* NULL, or 6 * probe_count bytes */
    /* plane_count * probe_count * 4 components in native byte order: texels_f32 when storage is
     * float (texels_f16 NULL), else texels_f16 (IEEE binary16 bit patterns; texels_f32 NULL). */
    size_t component_count;
    float* texels_f32;
    uint16_t* texels_f16;
} pkv_volume;

typedef struct pkv_file {
    uint32_t version; /* 1 or 2 */
    pkv_metadata metadata;
    size_t volume_count;
    pkv_volume* volumes;
} pkv_file;

/* Parses and checks a whole .pvol file held in memory. On PKV_OK, *out owns copies of
 * everything it points to (the bytes may be released at once) until pkv_free(out). On any
 * other status *out is left zeroed (pkv_free on it is harmless) and, when err is not NULL and
 * errcap > 0, err holds a NUL-terminated message naming the volume and the field, cut to
 * errcap bytes. */
pkv_status pkv_open_memory(const void* bytes, size_t size, pkv_file* out, char* err, size_t errcap);

/* Releases what pkv_open_memory allocated and zeroes *file. NULL is allowed. */
void pkv_free(pkv_file* file);

/* A short name for a status: "ok", "truncated", "checksum mismatch", ... */
const char* pkv_status_name(pkv_status status);

/* Component k (0..3) of texel plane `plane` at probe `probe`, as float (half decoded exactly).
 * Preconditions: plane < plane_count, probe < probe_count (not checked). */
void pkv_texel(const pkv_volume* volume, uint32_t plane, size_t probe, float out[4]);

/* The SH coefficients of one probe: sh[i][c] is coefficient i (Ramamoorthi-Hanrahan order) of
 * colour channel c (0 red, 1 green, 2 blue); coefficients 4..8 are zero for L1 volumes.
 * Preconditions: probe < probe_count (not checked). */
void pkv_probe_sh(const pkv_volume* volume, size_t probe, float sh[9][3]);

/* IEEE binary16 bit pattern to float (exact: every half is a float). */
float pkv_half_to_float(uint16_t bits);

/* xxHash64 of a byte range (the .pvol payload checksum uses seed 0). */
uint64_t pkv_xxhash64(const void* bytes, size_t size, uint64_t seed);

#ifdef __cplusplus
}
#endif

#endif /* PROBEKIT_PVOL_H */

#ifdef PROBEKIT_PVOL_IMPLEMENTATION
#ifndef PROBEKIT_PVOL_IMPLEMENTATION_DONE
#define PROBEKIT_PVOL_IMPLEMENTATION_DONE

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#if defined(PKV_MALLOC) != defined(PKV_FREE)
#error "define both PKV_MALLOC and PKV_FREE, or neither"
#endif
#ifndef PKV_MALLOC
#include <stdlib.h>
#define PKV_MALLOC(size) malloc(size)
#define PKV_FREE(pointer) free(pointer)
#endif

/* Header layout (pvol.hpp). */
#define PKV__HEADER_BYTES 32u
#define PKV__OLDEST_VERSION 1u
#define PKV__VERSION 2u
/* Smallest version-1 volume: layout, name length, bounds, resolution, position mode, rotation,
 * translation, sh order, storage, priority, fade, validity count, texel count (pvol.cpp's
 * kMinVolumeBytesV1); version 2 adds the visibility flag. */
#define PKV__MIN_VOLUME_BYTES_V1                                                                   \
    (1u + 8u + 24u + 12u + 1u + 16u + 12u + 1u + 1u + 4u + 4u + 8u + 8u)
#define PKV__BRICK_BYTES 13u  /* level u8, coord u32 x 3 */
#define PKV__BRICK_PROBES 64u /* 4 x 4 x 4 */
#define PKV__MAX_LEVEL 3u
#define PKV__MAX_FINEST_CELLS ((uint64_t)1 << 24) /* brick.hpp kMaxFinestCells */
#define PKV__MAX_RESOLUTION 256u
#define PKV__VISIBILITY_BYTES 6u
#define PKV__MAX_TEXEL_BITS 0x7149f2cau /* the float 1e30f (volume.hpp kMaxTexelMagnitude) */
#define PKV__UNCOVERED 0xffffffffu

/* ---- little-endian loads ------------------------------------------------------------------ */

static uint32_t pkv__le32(const uint8_t* p) {
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static uint64_t pkv__le64(const uint8_t* p) {
    return (uint64_t)pkv__le32(p) | (uint64_t)pkv__le32(p + 4) << 32;
}

static float pkv__float_from_bits(uint32_t bits) {
    float f;
    memcpy(&f, &bits, sizeof f);
    return f;
}

static int pkv__float_bits_finite(uint32_t bits) {
    return (bits & 0x7f800000u) != 0x7f800000u;
}

/* ---- xxHash64 (Yann Collet's algorithm; the project's own is formats/src/xxhash.cpp) -------- */

#define PKV__P1 0x9E3779B185EBCA87ull
#define PKV__P2 0xC2B2AE3D27D4EB4Full
#define PKV__P3 0x165667B19E3779F9ull
#define PKV__P4 0x85EBCA77C2B2AE63ull
#define PKV__P5 0x27D4EB2F165667C5ull

static uint64_t pkv__rotl(uint64_t x, int r) {
    return (x << r) | (x >> (64 - r));
}

static uint64_t pkv__xxh_round(uint64_t acc, uint64_t lane) {
    acc += lane * PKV__P2;
    return pkv__rotl(acc, 31) * PKV__P1;
}

static uint64_t pkv__xxh_merge(uint64_t hash, uint64_t acc) {
    hash ^= pkv__xxh_round(0, acc);
    return hash * PKV__P1 + PKV__P4;
}

uint64_t pkv_xxhash64(const void* bytes, size_t size, uint64_t seed) {
    const uint8_t* p = (const uint8_t*)bytes;
    const uint8_t* end = p + size;
    uint64_t hash;
    if (size >= 32) {
        uint64_t acc[4];
        int i;
        acc[0] = seed + PKV__P1 + PKV__P2;
        acc[1] = seed + PKV__P2;
        acc[2] = seed;
        acc[3] = seed - PKV__P1;
        for (; end - p >= 32; p += 32) {
            for (i = 0; i < 4; ++i) {
                acc[i] = pkv__xxh_round(acc[i], pkv__le64(p + 8 * i));
            }
        }
        hash = pkv__rotl(acc[0], 1) + pkv__rotl(acc[1], 7) + pkv__rotl(acc[2], 12) +
               pkv__rotl(acc[3], 18);
        for (i = 0; i < 4; ++i) {
            hash = pkv__xxh_merge(hash, acc[i]);
        }
    } else {
        hash = seed + PKV__P5;
    }
    hash += (uint64_t)size;
    for (; end - p >= 8; p += 8) {
        hash ^= pkv__xxh_round(0, pkv__le64(p));
        hash = pkv__rotl(hash, 27) * PKV__P1 + PKV__P4;
    }
    if (end - p >= 4) {
        hash ^= (uint64_t)pkv__le32(p) * PKV__P1;
        hash = pkv__rotl(hash, 23) * PKV__P2 + PKV__P3;
        p += 4;
    }
    for (; p < end; ++p) {
        hash ^= (uint64_t)*p * PKV__P5;
        hash = pkv__rotl(hash, 11) * PKV__P1;
    }
    hash ^= hash >> 33;
    hash *= PKV__P2;
    hash ^= hash >> 29;
    hash *= PKV__P3;
    hash ^= hash >> 32;
    return hash;
}

/* ---- half floats ---------------------------------------------------------------------------- */

float pkv_half_to_float(uint16_t bits) {
    const uint32_t sign = (uint32_t)(bits & 0x8000u) << 16;
    uint32_t exponent = (bits >> 10) & 0x1fu;
    uint32_t mantissa = bits & 0x3ffu;
    if (exponent == 0x1fu) { /* infinity or NaN */
        return pkv__float_from_bits(sign | 0x7f800000u | mantissa << 13);
    }
    if (exponent == 0) {
        if (mantissa == 0) {
            return pkv__float_from_bits(sign);
        }
        /* Subnormal: shift the leading 1 up to the implicit bit, one exponent step each. */
        exponent = 1;
        while ((mantissa & 0x400u) == 0) {
            mantissa <<= 1;
            --exponent;
        }
        mantissa &= 0x3ffu;
    }
    return pkv__float_from_bits(sign | (exponent + 112u) << 23 | mantissa << 13);
}

/* ---- the reader ----------------------------------------------------------------------------- */

typedef struct pkv__reader {
    const uint8_t* at;
    size_t left; /* payload bytes not yet read */
    uint32_t version;
    char* err;
    size_t errcap;
    char context[112]; /* "volume 3 ('name'): " while a volume is read */
} pkv__reader;

static pkv_status pkv__fail(pkv__reader* r, pkv_status status, const char* format, ...) {
    if (r->err != NULL && r->errcap > 0) {
        va_list args;
        const size_t used = strlen(r->context) < r->errcap ? strlen(r->context) : r->errcap - 1;
        memcpy(r->err, r->context, used);
        r->err[used] = '\0';
        va_start(args, format);
        vsnprintf(r->err + used, r->errcap - used, format, args);
        va_end(args);
    }
    return status;
}

#define PKV__TRY(call)                                                                             \
    do {                                                                                           \
        const pkv_status pkv__status = (call);                                                     \
        if (pkv__status != PKV_OK) {                                                               \
            return pkv__status;                                                                    \
        }                                                                                          \
    } while (0)

/* A fixed-size field: fails as truncated when fewer than `bytes` remain. */
static pkv_status pkv__take(pkv__reader* r, size_t bytes, const uint8_t** field, const char* what) {
    *field = r->at; /* set on failure too, which keeps compilers from seeing it unset */
    if (bytes > r->left) {
        return pkv__fail(r, PKV_ERROR_TRUNCATED, "payload ends early, inside %s", what);
    }
    r->at += bytes;
    r->left -= bytes;
    return PKV_OK;
}

static pkv_status pkv__u8(pkv__reader* r, uint8_t* value, const char* what) {
    const uint8_t* p;
    PKV__TRY(pkv__take(r, 1, &p, what));
    *value = p[0];
    return PKV_OK;
}

static pkv_status pkv__u32(pkv__reader* r, uint32_t* value, const char* what) {
    const uint8_t* p;
    PKV__TRY(pkv__take(r, 4, &p, what));
    *value = pkv__le32(p);
    return PKV_OK;
}

static pkv_status pkv__u64(pkv__reader* r, uint64_t* value, const char* what) {
    const uint8_t* p;
    PKV__TRY(pkv__take(r, 8, &p, what));
    *value = pkv__le64(p);
    return PKV_OK;
}

static pkv_status pkv__f32s(pkv__reader* r, float* values, int count, const char* what) {
    int i;
    for (i = 0; i < count; ++i) {
        uint32_t bits;
        PKV__TRY(pkv__u32(r, &bits, what));
        values[i] = pkv__float_from_bits(bits);
    }
    return PKV_OK;
}

/* Fails unless `count` elements of `element_bytes` each fit in what is left of the payload;
 * called before every allocation, so a forged count allocates nothing the file does not hold. */
static pkv_status pkv__require(pkv__reader* r, uint64_t count, size_t element_bytes,
                               const char* what) {
    if (count > (uint64_t)(r->left / element_bytes)) {
        char each[32] = "";
        if (element_bytes > 1) {
            snprintf(each, sizeof each, " (%u bytes each)", (unsigned)element_bytes);
        }
        return pkv__fail(r, PKV_ERROR_TRUNCATED,
                         "%s %llu%s needs more than the %llu payload bytes that remain", what,
                         (unsigned long long)count, each, (unsigned long long)r->left);
    }
    return PKV_OK;
}

static pkv_status pkv__alloc(pkv__reader* r, void** out, size_t count, size_t element_bytes) {
    *out = NULL;
    if (count == 0) {
        return PKV_OK;
    }
    if (count > (size_t)-1 / element_bytes || (*out = PKV_MALLOC(count * element_bytes)) == NULL) {
        return pkv__fail(r, PKV_ERROR_OUT_OF_MEMORY, "out of memory");
    }
    return PKV_OK;
}

static pkv_status pkv__string(pkv__reader* r, pkv_string* out, const char* what) {
    uint64_t length;
    const uint8_t* bytes;
    char* text;
    PKV__TRY(pkv__u64(r, &length, what));
    PKV__TRY(pkv__require(r, length, 1, what));
    PKV__TRY(pkv__alloc(r, (void**)&text, (size_t)length + 1, 1));
    PKV__TRY(pkv__take(r, (size_t)length, &bytes, what));
    if (length > 0) {
        memcpy(text, bytes, (size_t)length);
    }
    text[length] = '\0';
    out->data = text;
    out->size = (size_t)length;
    return PKV_OK;
}

/* "volume 3 ('name'): ", the name cut short and every byte outside printable ASCII shown as
 * '?', so that a message is safe to print whatever the file holds. */
static void pkv__set_volume_context(pkv__reader* r, size_t index, const pkv_string* name) {
    char shown[48];
    size_t i, n = name->size < sizeof shown - 1 ? name->size : sizeof shown - 1;
    for (i = 0; i < n; ++i) {
        const unsigned char c = (unsigned char)name->data[i];
        shown[i] = c >= 0x20 && c < 0x7f ? (char)c : '?';
    }
    shown[n] = '\0';
    snprintf(r->context, sizeof r->context, "volume %llu ('%s%s'): ", (unsigned long long)index,
             shown, name->size > n ? "..." : "");
}

/* The deepest nesting of JSON arrays and objects accepted in metadata.parameters_json, as
 * probekit's decoder accepts it (kMaxJsonDepth, formats/include/probekit/formats/
 * json_nesting.hpp): the readers that parse the parameters recurse once per level. Brackets
 * are counted outside strings, without parsing. */
#define PKV_MAX_JSON_DEPTH 64

static pkv_status pkv__json_nesting(pkv__reader* r, const pkv_string* json) {
    size_t i, depth = 0, deepest = 0, first_too_deep = 0;
    int in_string = 0;
    for (i = 0; i < json->size; ++i) {
        const char c = json->data[i];
        if (in_string) {
            if (c == '\\') {
                ++i; /* the escaped character cannot end the string */
            } else if (c == '"') {
                in_string = 0;
            }
        } else if (c == '"') {
            in_string = 1;
        } else if (c == '[' || c == '{') {
            if (++depth > deepest) {
                deepest = depth;
                if (depth == PKV_MAX_JSON_DEPTH + 1) {
                    first_too_deep = i;
                }
            }
        } else if ((c == ']' || c == '}') && depth > 0) {
            --depth;
        }
    }
    if (deepest > PKV_MAX_JSON_DEPTH) {
        return pkv__fail(r, PKV_ERROR_OUT_OF_RANGE,
                         "metadata.parameters_json: JSON arrays and objects nest %llu levels "
                         "deep (level %d opens at byte %llu), more than the limit of %d",
                         (unsigned long long)deepest, PKV_MAX_JSON_DEPTH + 1,
                         (unsigned long long)first_too_deep, PKV_MAX_JSON_DEPTH);
    }
    return PKV_OK;
}

static pkv_status pkv__metadata(pkv__reader* r, pkv_metadata* meta) {
    uint64_t bake_bits;
    PKV__TRY(pkv__string(r, &meta->tool_version, "metadata.tool_version length"));
    PKV__TRY(pkv__string(r, &meta->method, "metadata.method length"));
    PKV__TRY(pkv__string(r, &meta->parameters_json, "metadata.parameters_json length"));
    PKV__TRY(pkv__json_nesting(r, &meta->parameters_json));
    PKV__TRY(pkv__u64(r, &meta->seed, "metadata.seed"));
    PKV__TRY(pkv__u64(r, &meta->scene_hash, "metadata.scene_hash"));
    PKV__TRY(pkv__u64(r, &bake_bits, "metadata.bake_seconds"));
    memcpy(&meta->bake_seconds, &bake_bits, sizeof bake_bits);
    if ((bake_bits & 0x7ff0000000000000ull) == 0x7ff0000000000000ull) {
        return pkv__fail(r, PKV_ERROR_NON_FINITE, "metadata.bake_seconds is not finite");
    }
    return PKV_OK;
}

/* Bounds through fade distance, read unchecked (pvol.cpp reads them all before checking). */
static pkv_status pkv__volume_fields(pkv__reader* r, pkv_volume* v, uint8_t raw[3]) {
    PKV__TRY(pkv__f32s(r, v->bounds_min, 3, "bounds"));
    PKV__TRY(pkv__f32s(r, v->bounds_max, 3, "bounds"));
    PKV__TRY(pkv__u32(r, &v->resolution[0], "resolution"));
    PKV__TRY(pkv__u32(r, &v->resolution[1], "resolution"));
    PKV__TRY(pkv__u32(r, &v->resolution[2], "resolution"));
    PKV__TRY(pkv__u8(r, &raw[0], "position_mode"));
    PKV__TRY(pkv__f32s(r, v->rotation, 4, "frame.rotation"));
    PKV__TRY(pkv__f32s(r, v->translation, 3, "frame.translation"));
    PKV__TRY(pkv__u8(r, &raw[1], "sh_order"));
    PKV__TRY(pkv__u8(r, &raw[2], "storage"));
    PKV__TRY(pkv__u32(r, (uint32_t*)&v->blend_priority, "blend_priority"));
    return pkv__f32s(r, &v->fade_distance, 1, "fade_distance");
}

/* Position mode (centre only when bricked), SH order and storage. */
static pkv_status pkv__volume_enums(pkv__reader* r, pkv_volume* v, const uint8_t raw[3]) {
    if (raw[0] > PKV_POSITION_CORNER) {
        return pkv__fail(r, PKV_ERROR_BAD_ENUM, "position_mode %u is not 0 (center) or 1 (corner)",
                         raw[0]);
    }
    if (v->layout == PKV_LAYOUT_BRICKED && raw[0] != PKV_POSITION_CENTER) {
        return pkv__fail(r, PKV_ERROR_BAD_ENUM,
                         "position_mode %u of a bricked volume must be 0 (center)", raw[0]);
    }
    if (raw[1] != 1 && raw[1] != 2) {
        return pkv__fail(r, PKV_ERROR_BAD_ENUM, "sh_order %u is not 1 (L1) or 2 (L2)", raw[1]);
    }
    if (raw[2] > PKV_STORAGE_HALF) {
        return pkv__fail(r, PKV_ERROR_BAD_ENUM, "storage %u is not 0 (float) or 1 (half)", raw[2]);
    }
    v->position_mode = (pkv_position_mode)raw[0];
    v->sh_order = raw[1];
    v->coefficient_count = raw[1] == 1 ? 4u : 9u;
    v->plane_count = raw[1] == 1 ? 3u : 7u;
    v->storage = (pkv_storage)raw[2];
    return PKV_OK;
}

static uint32_t pkv__bits(float f) {
    uint32_t bits;
    memcpy(&bits, &f, sizeof bits);
    return bits;
}

/* Finiteness field by field, in pvol.cpp's order, so the message names the first bad one. */
static pkv_status pkv__volume_finite(pkv__reader* r, const pkv_volume* v) {
    static const char axes[3] = {'x', 'y', 'z'};
    int i;
    for (i = 0; i < 3; ++i) {
        if (!pkv__float_bits_finite(pkv__bits(v->bounds_min[i])) ||
            !pkv__float_bits_finite(pkv__bits(v->bounds_max[i]))) {
            return pkv__fail(r, PKV_ERROR_NON_FINITE, "bounds.%c is not finite", axes[i]);
        }
        if (!pkv__float_bits_finite(pkv__bits(v->translation[i]))) {
            return pkv__fail(r, PKV_ERROR_NON_FINITE, "frame.translation.%c is not finite",
                             axes[i]);
        }
    }
    for (i = 0; i < 4; ++i) {
        if (!pkv__float_bits_finite(pkv__bits(v->rotation[i]))) {
            return pkv__fail(r, PKV_ERROR_NON_FINITE, "frame.rotation is not finite");
        }
    }
    if (!pkv__float_bits_finite(pkv__bits(v->fade_distance))) {
        return pkv__fail(r, PKV_ERROR_NON_FINITE, "fade_distance is not finite");
    }
    return PKV_OK;
}

/* Resolution, bound ordering and the unit quaternion (grid.cpp's GridLayout::make). */
static pkv_status pkv__volume_grid(pkv__reader* r, const pkv_volume* v) {
    static const char axes[3] = {'x', 'y', 'z'};
    float w2, x2, y2, z2, length;
    int i;
    for (i = 0; i < 3; ++i) {
        const uint32_t res = v->resolution[i];
        if (res < 1 || res > PKV__MAX_RESOLUTION) {
            return pkv__fail(r, PKV_ERROR_BAD_RESOLUTION, "resolution.%c = %lu is outside 1..256",
                             axes[i], (unsigned long)res);
        }
        if ((res & (res - 1)) != 0) {
            return pkv__fail(r, PKV_ERROR_BAD_RESOLUTION,
                             "resolution.%c = %lu is not a power of two", axes[i],
                             (unsigned long)res);
        }
        if (v->position_mode == PKV_POSITION_CORNER && res < 2) {
            return pkv__fail(r, PKV_ERROR_BAD_RESOLUTION,
                             "resolution.%c = %lu is too small for corner placement (needs >= 2)",
                             axes[i], (unsigned long)res);
        }
    }
    for (i = 0; i < 3; ++i) {
        if (!(v->bounds_max[i] > v->bounds_min[i])) {
            return pkv__fail(r, PKV_ERROR_OUT_OF_RANGE,
                             "bounds.%c is empty or inverted (min %g >= max %g)", axes[i],
                             (double)v->bounds_min[i], (double)v->bounds_max[i]);
        }
    }
    /* Rounded as the C++ decoder rounds it (GLM's quaternion dot: (ww + xx) + (yy + zz)), one
     * product per statement so that no compiler fuses them. */
    w2 = v->rotation[0] * v->rotation[0];
    x2 = v->rotation[1] * v->rotation[1];
    y2 = v->rotation[2] * v->rotation[2];
    z2 = v->rotation[3] * v->rotation[3];
    w2 = w2 + x2;
    y2 = y2 + z2;
    length = sqrtf(w2 + y2);
    if (fabsf(length - 1.0f) > 1e-3f) {
        return pkv__fail(r, PKV_ERROR_OUT_OF_RANGE, "frame.rotation is not a unit quaternion");
    }
    return PKV_OK;
}

/* The brick list and the indirection, whose construction is the tiling check (brick.cpp's
 * buildIndirection). */
static pkv_status pkv__bricks(pkv__reader* r, pkv_volume* v) {
    uint8_t max_level;
    uint64_t count, cells, c;
    size_t i;
    uint32_t level;
    PKV__TRY(pkv__u8(r, &max_level, "max_level"));
    PKV__TRY(pkv__u64(r, &count, "brick count"));
    PKV__TRY(pkv__require(r, count, PKV__BRICK_BYTES, "brick count"));
    PKV__TRY(pkv__alloc(r, (void**)&v->bricks, (size_t)count, sizeof(pkv_brick)));
    v->brick_count = (size_t)count;
    v->max_level = max_level;
    for (i = 0; i < v->brick_count; ++i) {
        pkv_brick* b = &v->bricks[i];
        uint8_t brick_level;
        PKV__TRY(pkv__u8(r, &brick_level, "brick"));
        PKV__TRY(pkv__u32(r, &b->coord[0], "brick"));
        PKV__TRY(pkv__u32(r, &b->coord[1], "brick"));
        PKV__TRY(pkv__u32(r, &b->coord[2], "brick"));
        b->level = brick_level;
    }
    if (count < (uint64_t)v->resolution[0] * v->resolution[1] * v->resolution[2]) {
        return pkv__fail(r, PKV_ERROR_INCONSISTENT_SIZE,
                         "%llu bricks cannot cover the %lux%lux%lu level-0 grid (every level-0 "
                         "region needs a brick)",
                         (unsigned long long)count, (unsigned long)v->resolution[0],
                         (unsigned long)v->resolution[1], (unsigned long)v->resolution[2]);
    }
    PKV__TRY(pkv__require(
        r, count * PKV__BRICK_PROBES,
        1 + (size_t)(v->plane_count * 4u * (v->storage == PKV_STORAGE_FLOAT ? 4u : 2u)),
        "probe count of the bricks"));
    if (max_level > PKV__MAX_LEVEL) {
        return pkv__fail(r, PKV_ERROR_OUT_OF_RANGE, "max_level %u exceeds 3", max_level);
    }
    for (i = 0; i < 3; ++i) {
        v->finest_cells[i] = v->resolution[i] << max_level;
    }
    cells = (uint64_t)v->finest_cells[0] * v->finest_cells[1] * v->finest_cells[2];
    if (cells > PKV__MAX_FINEST_CELLS) {
        return pkv__fail(r, PKV_ERROR_OUT_OF_RANGE,
                         "%llu finest cells exceed the limit of 16777216 (fewer levels or top "
                         "bricks)",
                         (unsigned long long)cells);
    }
    if (count >= 0xffffffffu) {
        return pkv__fail(r, PKV_ERROR_OUT_OF_RANGE, "too many bricks");
    }
    for (i = 0; i < v->brick_count; ++i) {
        const pkv_brick* b = &v->bricks[i];
        int a;
        if (b->level > max_level) {
            return pkv__fail(r, PKV_ERROR_OUT_OF_RANGE,
                             "brick %llu: level %lu exceeds max_level %u", (unsigned long long)i,
                             (unsigned long)b->level, max_level);
        }
        for (a = 0; a < 3; ++a) {
            if (b->coord[a] >= v->resolution[a] << b->level) {
                return pkv__fail(r, PKV_ERROR_OUT_OF_RANGE,
                                 "brick %llu (level %lu): coord outside the level's grid",
                                 (unsigned long long)i, (unsigned long)b->level);
            }
        }
    }
    PKV__TRY(pkv__alloc(r, (void**)&v->indirection, (size_t)cells, sizeof(uint32_t)));
    for (c = 0; c < cells; ++c) {
        v->indirection[c] = PKV__UNCOVERED;
    }
    /* Coarse levels first (each level's bricks in list order): a finer brick then overwrites
     * the cells it covers, and meeting an entry of the same level means a repeated brick. */
    for (level = 0; level <= max_level; ++level) {
        const uint32_t span = 1u << (max_level - level);
        for (i = 0; i < v->brick_count; ++i) {
            const pkv_brick* b = &v->bricks[i];
            uint32_t x, y, z;
            if (b->level != level) {
                continue;
            }
            for (z = b->coord[2] * span; z < (b->coord[2] + 1) * span; ++z) {
                for (y = b->coord[1] * span; y < (b->coord[1] + 1) * span; ++y) {
                    for (x = b->coord[0] * span; x < (b->coord[0] + 1) * span; ++x) {
                        uint32_t* entry =
                            &v->indirection[x + (size_t)v->finest_cells[0] *
                                                    (y + (size_t)v->finest_cells[1] * z)];
                        if (*entry != PKV__UNCOVERED && v->bricks[*entry].level == level) {
                            return pkv__fail(r, PKV_ERROR_INCONSISTENT_SIZE,
                                             "brick %llu repeats brick %lu", (unsigned long long)i,
                                             (unsigned long)*entry);
                        }
                        *entry = (uint32_t)i;
                    }
                }
            }
        }
    }
    for (c = 0; c < cells; ++c) {
        if (v->indirection[c] == PKV__UNCOVERED) {
            return pkv__fail(r, PKV_ERROR_INCONSISTENT_SIZE,
                             "finest cell %llu (x fastest) is covered by no brick",
                             (unsigned long long)c);
        }
    }
    return PKV_OK;
}

static pkv_status pkv__validity(pkv__reader* r, pkv_volume* v) {
    uint64_t count;
    const uint8_t* bytes;
    PKV__TRY(pkv__u64(r, &count, "validity byte count"));
    if (count != (uint64_t)v->probe_count) {
        return pkv__fail(r, PKV_ERROR_INCONSISTENT_SIZE,
                         "validity holds %llu bytes but the volume has %llu probes",
                         (unsigned long long)count, (unsigned long long)v->probe_count);
    }
    PKV__TRY(pkv__require(r, count, 1, "validity byte count"));
    PKV__TRY(pkv__alloc(r, (void**)&v->validity, v->probe_count, 1));
    PKV__TRY(pkv__take(r, v->probe_count, &bytes, "validity"));
    if (v->probe_count > 0) {
        memcpy(v->validity, bytes, v->probe_count);
    }
    return PKV_OK;
}

/* Names the bad texel at plane-major component `index` (NaN, infinity or beyond 1e30). */
static pkv_status pkv__texel_fault(pkv__reader* r, const pkv_volume* v, size_t index, float value) {
    const size_t texel = index / 4;
    const int finite = pkv__float_bits_finite(pkv__bits(value));
    return pkv__fail(
        r, finite ? PKV_ERROR_OUT_OF_RANGE : PKV_ERROR_NON_FINITE,
        "probe %llu (plane %llu, component %u) holds %g%s",
        (unsigned long long)(texel % v->probe_count), (unsigned long long)(texel / v->probe_count),
        (unsigned)(index % 4), (double)value,
        finite ? ", more than the texel magnitude bound 1e+30" : "; every texel must be finite");
}

static pkv_status pkv__texels(pkv__reader* r, pkv_volume* v) {
    uint64_t count;
    const size_t bytes_per = v->storage == PKV_STORAGE_FLOAT ? 4 : 2;
    const uint8_t* p;
    size_t i;
    v->component_count = (size_t)v->plane_count * v->probe_count * 4;
    PKV__TRY(pkv__u64(r, &count, "texel count"));
    if (count != (uint64_t)v->component_count) {
        return pkv__fail(r, PKV_ERROR_INCONSISTENT_SIZE,
                         "texel data holds %llu values, expected %llu (%lu planes x %llu probes "
                         "x 4)",
                         (unsigned long long)count, (unsigned long long)v->component_count,
                         (unsigned long)v->plane_count, (unsigned long long)v->probe_count);
    }
    PKV__TRY(pkv__require(r, count, bytes_per,
                          bytes_per == 4 ? "float texel count" : "half texel count"));
    if (v->storage == PKV_STORAGE_FLOAT) {
        PKV__TRY(pkv__alloc(r, (void**)&v->texels_f32, v->component_count, sizeof(float)));
    } else {
        PKV__TRY(pkv__alloc(r, (void**)&v->texels_f16, v->component_count, sizeof(uint16_t)));
    }
    PKV__TRY(pkv__take(r, v->component_count * bytes_per, &p, "texels"));
    for (i = 0; i < v->component_count; ++i) {
        if (v->storage == PKV_STORAGE_FLOAT) {
            const uint32_t bits = pkv__le32(p + 4 * i);
            v->texels_f32[i] = pkv__float_from_bits(bits);
            /* Beyond 1e30, infinite or NaN: the bits without the sign exceed 1e30's. */
            if ((bits & 0x7fffffffu) > PKV__MAX_TEXEL_BITS) {
                return pkv__texel_fault(r, v, i, v->texels_f32[i]);
            }
        } else {
            const uint16_t bits = (uint16_t)(p[2 * i] | p[2 * i + 1] << 8);
            v->texels_f16[i] = bits;
            if ((bits & 0x7c00u) == 0x7c00u) { /* every finite half is within bounds */
                return pkv__texel_fault(r, v, i, pkv_half_to_float(bits));
            }
        }
    }
    return PKV_OK;
}

static pkv_status pkv__visibility(pkv__reader* r, pkv_volume* v) {
    uint8_t flag;
    const uint8_t* bytes;
    PKV__TRY(pkv__u8(r, &flag, "visibility flag"));
    if (flag == 0) {
        return PKV_OK;
    }
    if (flag != 1) {
        return pkv__fail(r, PKV_ERROR_BAD_ENUM, "visibility flag %u is not 0 (none) or 1 (present)",
                         flag);
    }
    PKV__TRY(pkv__require(r, v->probe_count, PKV__VISIBILITY_BYTES, "visibility probe count"));
    PKV__TRY(pkv__alloc(r, (void**)&v->visibility, v->probe_count, PKV__VISIBILITY_BYTES));
    PKV__TRY(pkv__take(r, v->probe_count * PKV__VISIBILITY_BYTES, &bytes, "visibility"));
    if (v->probe_count > 0) {
        memcpy(v->visibility, bytes, v->probe_count * PKV__VISIBILITY_BYTES);
    }
    return PKV_OK;
}

/* The checks pvol.cpp leaves to validateVolumeStructure, after the probe data. */
static pkv_status pkv__volume_structure(pkv__reader* r, const pkv_volume* v) {
    size_t i;
    if (v->fade_distance < 0.0f) {
        return pkv__fail(r, PKV_ERROR_OUT_OF_RANGE, "fade_distance must be finite and >= 0");
    }
    for (i = 0; i < v->probe_count; ++i) {
        if (v->validity[i] > 1) {
            return pkv__fail(r, PKV_ERROR_OUT_OF_RANGE, "validity byte %u is not 0 or 1",
                             v->validity[i]);
        }
    }
    return PKV_OK;
}

static pkv_status pkv__volume(pkv__reader* r, size_t index, pkv_volume* v) {
    uint8_t layout, raw[3];
    snprintf(r->context, sizeof r->context, "volume %llu: ", (unsigned long long)index);
    PKV__TRY(pkv__u8(r, &layout, "layout"));
    if (layout > PKV_LAYOUT_BRICKED) {
        return pkv__fail(r, PKV_ERROR_BAD_ENUM,
                         "layout %u is not a known layout (0 = dense, 1 = bricked)", layout);
    }
    v->layout = (pkv_layout)layout;
    PKV__TRY(pkv__string(r, &v->name, "name length"));
    pkv__set_volume_context(r, index, &v->name);
    PKV__TRY(pkv__volume_fields(r, v, raw));
    PKV__TRY(pkv__volume_enums(r, v, raw));
    PKV__TRY(pkv__volume_finite(r, v));
    PKV__TRY(pkv__volume_grid(r, v));
    if (v->layout == PKV_LAYOUT_BRICKED) {
        PKV__TRY(pkv__bricks(r, v));
        v->probe_count = v->brick_count * PKV__BRICK_PROBES;
    } else {
        v->probe_count = (size_t)v->resolution[0] * v->resolution[1] * v->resolution[2];
    }
    PKV__TRY(pkv__validity(r, v));
    PKV__TRY(pkv__texels(r, v));
    if (r->version >= 2) {
        PKV__TRY(pkv__visibility(r, v));
    }
    return pkv__volume_structure(r, v);
}

/* Magic, version, header size, payload size against the bytes that follow, checksum. */
static pkv_status pkv__header(pkv__reader* r, const uint8_t* bytes, size_t size) {
    static const uint8_t magic[8] = {'P', 'K', 'V', 'O', 'L', '\r', '\n', 0x1a};
    uint32_t header_bytes;
    uint64_t payload_bytes;
    /* A short file that does not start like a .pvol is "not a .pvol", not "truncated". */
    if (memcmp(bytes, magic, size < 8 ? size : 8) != 0) {
        return pkv__fail(r, PKV_ERROR_BAD_MAGIC, "not a .pvol file (bad magic bytes)");
    }
    if (size < PKV__HEADER_BYTES) {
        return pkv__fail(r, PKV_ERROR_TRUNCATED,
                         "file is %llu bytes, shorter than the 32-byte header",
                         (unsigned long long)size);
    }
    r->version = pkv__le32(bytes + 8);
    if (r->version < PKV__OLDEST_VERSION || r->version > PKV__VERSION) {
        return pkv__fail(r, PKV_ERROR_UNSUPPORTED_VERSION,
                         "format version %lu is not supported; this reader reads versions 1 to 2",
                         (unsigned long)r->version);
    }
    header_bytes = pkv__le32(bytes + 12);
    if (header_bytes != PKV__HEADER_BYTES) {
        return pkv__fail(r, PKV_ERROR_INCONSISTENT_SIZE, "header size %lu is not 32 bytes",
                         (unsigned long)header_bytes);
    }
    payload_bytes = pkv__le64(bytes + 16);
    if (payload_bytes > (uint64_t)(size - PKV__HEADER_BYTES)) {
        return pkv__fail(
            r, PKV_ERROR_TRUNCATED, "header promises %llu payload bytes but the file holds %llu",
            (unsigned long long)payload_bytes, (unsigned long long)(size - PKV__HEADER_BYTES));
    }
    if (payload_bytes < (uint64_t)(size - PKV__HEADER_BYTES)) {
        return pkv__fail(r, PKV_ERROR_TRAILING_BYTES, "%llu bytes follow the %llu-byte payload",
                         (unsigned long long)(size - PKV__HEADER_BYTES - payload_bytes),
                         (unsigned long long)payload_bytes);
    }
    if (pkv_xxhash64(bytes + PKV__HEADER_BYTES, size - PKV__HEADER_BYTES, 0) !=
        pkv__le64(bytes + 24)) {
        return pkv__fail(r, PKV_ERROR_CHECKSUM_MISMATCH,
                         "payload checksum does not match the header (file corrupt)");
    }
    r->at = bytes + PKV__HEADER_BYTES;
    r->left = size - PKV__HEADER_BYTES;
    return PKV_OK;
}

static pkv_status pkv__file(pkv__reader* r, const uint8_t* bytes, size_t size, pkv_file* out) {
    uint8_t order_flag;
    uint64_t count;
    size_t i;
    size_t min_volume_bytes;
    PKV__TRY(pkv__header(r, bytes, size));
    min_volume_bytes = PKV__MIN_VOLUME_BYTES_V1 + (r->version >= 2 ? 1u : 0u);
    out->version = r->version;
    if (r->left == 0) {
        return pkv__fail(r, PKV_ERROR_TRUNCATED, "payload is empty");
    }
    /* The serialiser's byte-order flag: files are always written little-endian (1). */
    PKV__TRY(pkv__u8(r, &order_flag, "byte-order flag"));
    if (order_flag != 1) {
        return pkv__fail(r, PKV_ERROR_BAD_ENUM,
                         "payload byte-order flag %u is not 1 (little-endian)", order_flag);
    }
    PKV__TRY(pkv__metadata(r, &out->metadata));
    PKV__TRY(pkv__u64(r, &count, "volume count"));
    if (count > (uint64_t)(r->left / min_volume_bytes)) {
        return pkv__fail(r, PKV_ERROR_TRUNCATED,
                         "volume count %llu needs at least %u bytes each but only %llu payload "
                         "bytes remain",
                         (unsigned long long)count, (unsigned)min_volume_bytes,
                         (unsigned long long)r->left);
    }
    PKV__TRY(pkv__alloc(r, (void**)&out->volumes, (size_t)count, sizeof(pkv_volume)));
    if (count > 0) {
        memset(out->volumes, 0, (size_t)count * sizeof(pkv_volume));
    }
    out->volume_count = (size_t)count;
    for (i = 0; i < out->volume_count; ++i) {
        PKV__TRY(pkv__volume(r, i, &out->volumes[i]));
    }
    r->context[0] = '\0';
    if (r->left != 0) {
        return pkv__fail(r, PKV_ERROR_TRAILING_BYTES,
                         "%llu unread payload bytes after the last volume",
                         (unsigned long long)r->left);
    }
    return PKV_OK;
}

pkv_status pkv_open_memory(const void* bytes, size_t size, pkv_file* out, char* err,
                           size_t errcap) {
    pkv__reader r;
    pkv_status status;
    memset(&r, 0, sizeof r);
    r.err = err;
    r.errcap = errcap;
    if (err != NULL && errcap > 0) {
        err[0] = '\0';
    }
    if (out == NULL || (bytes == NULL && size > 0)) {
        return pkv__fail(&r, PKV_ERROR_INVALID_ARGUMENT, "pkv_open_memory: null argument");
    }
    memset(out, 0, sizeof *out);
    if (size == 0) {
        return pkv__fail(&r, PKV_ERROR_TRUNCATED,
                         "file is 0 bytes, shorter than the 32-byte header");
    }
    status = pkv__file(&r, (const uint8_t*)bytes, size, out);
    if (status != PKV_OK) {
        pkv_free(out);
    }
    return status;
}

static void pkv__free_string(pkv_string* s) {
    PKV_FREE((void*)s->data);
}

void pkv_free(pkv_file* file) {
    size_t i;
    if (file == NULL) {
        return;
    }
    pkv__free_string(&file->metadata.tool_version);
    pkv__free_string(&file->metadata.method);
    pkv__free_string(&file->metadata.parameters_json);
    for (i = 0; i < file->volume_count; ++i) {
        pkv_volume* v = &file->volumes[i];
        pkv__free_string(&v->name);
        PKV_FREE(v->bricks);
        PKV_FREE(v->indirection);
        PKV_FREE(v->validity);
        PKV_FREE(v->visibility);
        PKV_FREE(v->texels_f32);
        PKV_FREE(v->texels_f16);
    }
    PKV_FREE(file->volumes);
    memset(file, 0, sizeof *file);
}

const char* pkv_status_name(pkv_status status) {
    switch (status) {
    case PKV_OK:
        return "ok";
    case PKV_ERROR_BAD_MAGIC:
        return "bad magic";
    case PKV_ERROR_UNSUPPORTED_VERSION:
        return "unsupported version";
    case PKV_ERROR_TRUNCATED:
        return "truncated";
    case PKV_ERROR_TRAILING_BYTES:
        return "trailing bytes";
    case PKV_ERROR_CHECKSUM_MISMATCH:
        return "checksum mismatch";
    case PKV_ERROR_INCONSISTENT_SIZE:
        return "inconsistent size";
    case PKV_ERROR_BAD_RESOLUTION:
        return "bad resolution";
    case PKV_ERROR_NON_FINITE:
        return "non-finite";
    case PKV_ERROR_OUT_OF_RANGE:
        return "out of range";
    case PKV_ERROR_BAD_ENUM:
        return "bad enum";
    case PKV_ERROR_INVALID_ARGUMENT:
        return "invalid argument";
    case PKV_ERROR_OUT_OF_MEMORY:
        return "out of memory";
    }
    return "unknown";
}

void pkv_texel(const pkv_volume* volume, uint32_t plane, size_t probe, float out[4]) {
    const size_t base = 4 * ((size_t)plane * volume->probe_count + probe);
    int k;
    for (k = 0; k < 4; ++k) {
        out[k] = volume->storage == PKV_STORAGE_FLOAT
                     ? volume->texels_f32[base + k]
                     : pkv_half_to_float(volume->texels_f16[base + k]);
    }
}

void pkv_probe_sh(const pkv_volume* volume, size_t probe, float sh[9][3]) {
    float texels[7][4];
    uint32_t p;
    int i, c, j;
    for (p = 0; p < volume->plane_count; ++p) {
        pkv_texel(volume, p, probe, texels[p]);
    }
    /* Planes 0..2: (L00, L1-1, L10, L11) of red, green, blue. */
    for (c = 0; c < 3; ++c) {
        for (i = 0; i < 4; ++i) {
            sh[i][c] = texels[c][i];
        }
    }
    /* Band 2 value j = 3 k + c (k = coefficient 4..8 less 4) at plane 3 + j / 4, component
     * j % 4 (volume.hpp). */
    for (j = 0; j < 15; ++j) {
        sh[4 + j / 3][j % 3] = volume->plane_count == 7 ? texels[3 + j / 4][j % 4] : 0.0f;
    }
}

#endif /* PROBEKIT_PVOL_IMPLEMENTATION_DONE */
#endif /* PROBEKIT_PVOL_IMPLEMENTATION */
