/* Reads a .pvol file with probekit_pvol.h, prints a summary of it and the irradiance E(n) that
 * one probe gives a surface facing +Y.
 *
 *     probekit_pvol_c_example scene.pvol [volume] [probe]
 *
 * E(n) = sum over l, m of A_l L_lm Y_lm(n), A = (pi, 2 pi / 3, pi / 4) for bands 0, 1, 2: the
 * irradiance of formats/CONVENTIONS.md ("Spherical harmonics"), in W/m^2, not divided by pi.
 */
#define PROBEKIT_PVOL_IMPLEMENTATION
#include "probekit_pvol.h"

#include <stdio.h>
#include <stdlib.h>

/* The whole file in memory (NULL on failure, with a message printed). */
static unsigned char* read_file(const char* path, size_t* size) {
    FILE* file = fopen(path, "rb");
    unsigned char* bytes = NULL;
    size_t capacity = 0;
    *size = 0;
    if (file == NULL) {
        perror(path);
        return NULL;
    }
    for (;;) {
        if (*size == capacity) {
            unsigned char* grown;
            capacity = capacity == 0 ? 65536 : 2 * capacity;
            grown = (unsigned char*)realloc(bytes, capacity);
            if (grown == NULL) {
                fprintf(stderr, "%s: out of memory\n", path);
                free(bytes);
                fclose(file);
                return NULL;
            }
            bytes = grown;
        }
        *size += fread(bytes + *size, 1, capacity - *size, file);
        if (*size < capacity) {
            break;
        }
    }
    if (ferror(file)) {
        perror(path);
        free(bytes);
        bytes = NULL;
    }
    fclose(file);
    return bytes;
}

/* Irradiance at unit normal n from one probe's radiance SH (Ramamoorthi-Hanrahan order). */
static void irradiance(float sh[9][3], uint32_t sh_order, const float n[3], float e[3]) {
    const float pi = 3.14159265f;
    const float x = n[0], y = n[1], z = n[2];
    const float basis[9] = {0.282095f,
                            0.488603f * y,
                            0.488603f * z,
                            0.488603f * x,
                            1.092548f * x * y,
                            1.092548f * y * z,
                            0.315392f * (3.0f * z * z - 1.0f),
                            1.092548f * x * z,
                            0.546274f * (x * x - y * y)};
    const float band_weight[9] = {pi,     2 * pi / 3, 2 * pi / 3, 2 * pi / 3, pi / 4,
                                  pi / 4, pi / 4,     pi / 4,     pi / 4};
    const int count = sh_order == 1 ? 4 : 9;
    int c, i;
    for (c = 0; c < 3; ++c) {
        e[c] = 0.0f;
        for (i = 0; i < count; ++i) {
            e[c] += band_weight[i] * sh[i][c] * basis[i];
        }
    }
}

/* Bytes of the file's text shown as they are when printable ASCII, else as '?'. */
static void print_text(const pkv_string* text) {
    size_t i;
    for (i = 0; i < text->size; ++i) {
        const unsigned char c = (unsigned char)text->data[i];
        putchar(c >= 0x20 && c < 0x7f ? c : '?');
    }
}

static void print_volume(size_t index, const pkv_volume* v) {
    size_t i, valid = 0;
    for (i = 0; i < v->probe_count; ++i) {
        valid += v->validity[i];
    }
    printf("volume %lu '", (unsigned long)index);
    print_text(&v->name);
    printf("': %s, %lux%lux%lu %s, L%lu (%lu coefficients) %s, %lu probes (%lu valid)%s\n",
           v->layout == PKV_LAYOUT_DENSE ? "dense" : "bricked", (unsigned long)v->resolution[0],
           (unsigned long)v->resolution[1], (unsigned long)v->resolution[2],
           v->layout == PKV_LAYOUT_DENSE
               ? (v->position_mode == PKV_POSITION_CENTER ? "probes (center)" : "probes (corner)")
               : "level-0 bricks",
           (unsigned long)v->sh_order, (unsigned long)v->coefficient_count,
           v->storage == PKV_STORAGE_FLOAT ? "float" : "half", (unsigned long)v->probe_count,
           (unsigned long)valid, v->visibility != NULL ? ", visibility" : "");
    printf("  bounds (%g, %g, %g) .. (%g, %g, %g), rotation (w %g, %g, %g, %g), translation "
           "(%g, %g, %g)\n",
           v->bounds_min[0], v->bounds_min[1], v->bounds_min[2], v->bounds_max[0], v->bounds_max[1],
           v->bounds_max[2], v->rotation[0], v->rotation[1], v->rotation[2], v->rotation[3],
           v->translation[0], v->translation[1], v->translation[2]);
    if (v->layout == PKV_LAYOUT_BRICKED) {
        printf("  %lu bricks, max level %lu\n", (unsigned long)v->brick_count,
               (unsigned long)v->max_level);
    }
}

int main(int argc, char** argv) {
    static const float up[3] = {0.0f, 1.0f, 0.0f};
    unsigned char* bytes;
    size_t size, volume_index, probe, i;
    pkv_file file;
    pkv_status status;
    char error[256];
    float sh[9][3], e[3];
    if (argc < 2 || argc > 4) {
        fprintf(stderr, "usage: %s file.pvol [volume] [probe]\n", argv[0]);
        return 2;
    }
    volume_index = argc > 2 ? (size_t)strtoul(argv[2], NULL, 10) : 0;
    probe = argc > 3 ? (size_t)strtoul(argv[3], NULL, 10) : 0;
    bytes = read_file(argv[1], &size);
    if (bytes == NULL) {
        return 1;
    }
    status = pkv_open_memory(bytes, size, &file, error, sizeof error);
    free(bytes); /* the pkv_file holds its own copies */
    if (status != PKV_OK) {
        fprintf(stderr, "%s: %s: %s\n", argv[1], pkv_status_name(status), error);
        return 1;
    }

    printf("%s: .pvol version %lu, made by '", argv[1], (unsigned long)file.version);
    print_text(&file.metadata.tool_version);
    printf("' with method '");
    print_text(&file.metadata.method);
    printf("', seed %llu, %lu volume(s)\n", (unsigned long long)file.metadata.seed,
           (unsigned long)file.volume_count);
    for (i = 0; i < file.volume_count; ++i) {
        print_volume(i, &file.volumes[i]);
    }

    if (volume_index < file.volume_count && probe < file.volumes[volume_index].probe_count) {
        const pkv_volume* v = &file.volumes[volume_index];
        pkv_probe_sh(v, probe, sh);
        irradiance(sh, v->sh_order, up, e);
        printf("volume %lu probe %lu: E(+Y) = (%g, %g, %g) W/m^2\n", (unsigned long)volume_index,
               (unsigned long)probe, e[0], e[1], e[2]);
    } else {
        printf("no probe %lu in volume %lu\n", (unsigned long)probe, (unsigned long)volume_index);
    }
    pkv_free(&file);
    return 0;
}
