/* A C program that reads a mesobake package through the C ABI: its grids, its sections
 * (with a checksum of their bytes), the GDM at every voxel of the middle layer along
 * every direction bin, and where the package holds radiance transfer, the RTV's transfer at
 * every voxel of that layer towards the last view bin and every vertex's PRT matrix. tests/c_program.rs compiles it and compares its output with the Rust
 * reader's. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "mesobake_package.h"

int main(int argc, char **argv) {
    if (argc != 2 && argc != 3) {
        fprintf(stderr, "usage: reader PACKAGE [MAX_BYTES]\n");
        return 2;
    }
    uint64_t max_bytes = argc == 3 ? strtoull(argv[2], NULL, 10) : (uint64_t)1 << 30;
    char error[256];
    MbpkgPackage *package = mbpkg_open(argv[1], max_bytes, error, sizeof error);
    if (package == NULL) {
        printf("error: %s\n", error);
        return 1;
    }
    /* The same bytes in memory: mbpkg_parse gives the same package, and refuses them under a
       limit below their size. */
    FILE *file = fopen(argv[1], "rb");
    if (file == NULL) return 9;
    fseek(file, 0, SEEK_END);
    size_t len = (size_t)ftell(file);
    fseek(file, 0, SEEK_SET);
    uint8_t *data = malloc(len);
    if (data == NULL || fread(data, 1, len, file) != len) return 9;
    fclose(file);
    MbpkgPackage *copy = mbpkg_parse(data, len, max_bytes, error, sizeof error);
    if (copy == NULL || mbpkg_section_count(copy) != mbpkg_section_count(package)) return 10;
    mbpkg_close(copy);
    if (mbpkg_parse(data, len, len - 1, error, sizeof error) != NULL) return 11;
    free(data);
    MbpkgGrid grid = mbpkg_grid(package);
    printf("codec %u\n", (unsigned)mbpkg_codec(package));
    printf("grid %ux%ux%u dirs %ux%u\n", grid.res[0], grid.res[1], grid.res[2], grid.dirs[0],
           grid.dirs[1]);
    printf("manifest %s\n", strstr(mbpkg_manifest_json(package), "\"format\":\"mesobake-package\"")
                                ? "ok" : "unexpected");
    for (size_t s = 0; s < mbpkg_section_count(package); s++) {
        MbpkgSection section;
        if (!mbpkg_section(package, s, &section)) return 3;
        uint32_t sum = 0;
        for (size_t b = 0; b < section.len; b++) sum = sum * 31u + section.data[b];
        printf("section %s dimension %u format %u %ux%ux%u bytes %zu sum %08x\n", section.name,
               (unsigned)section.dimension, (unsigned)section.format, section.width,
               section.height, section.depth, section.len, sum);
    }
    MbpkgSection none;
    if (mbpkg_section(package, mbpkg_section_count(package), &none)) return 4;
    uint32_t k = grid.res[2] / 2;
    for (uint32_t a = 0; a < grid.dirs[0]; a++)
        for (uint32_t b = 0; b < grid.dirs[1]; b++)
            for (uint32_t j = 0; j < grid.res[1]; j++)
                for (uint32_t i = 0; i < grid.res[0]; i++) {
                    float d = -1.0f;
                    int hit = mbpkg_distance(package, i, j, k, a, b, &d);
                    if (hit == 1) printf("%.6f\n", d);
                    else if (hit == 0) printf("escape\n");
                    else return 5;
                }
    float d;
    if (mbpkg_distance(package, grid.res[0], 0, 0, 0, 0, &d) != -1) return 6;
    float t[48];
    if (mbpkg_rtv_transfer(package, 0, 0, 0, 0, 0, t) == -1) {
        printf("no radiance transfer\n");
    } else {
        uint32_t a = grid.dirs[0] - 1, b = grid.dirs[1] - 1;
        for (uint32_t j = 0; j < grid.res[1]; j++)
            for (uint32_t i = 0; i < grid.res[0]; i++) {
                int sample = mbpkg_rtv_transfer(package, i, j, k, a, b, t);
                if (sample == 0) {
                    printf("not a sample\n");
                    continue;
                }
                if (sample != 1) return 7;
                for (int m = 0; m < 48; m++) printf("%.6f%c", t[m], m == 47 ? '\n' : ' ');
            }
        if (mbpkg_rtv_transfer(package, 0, 0, 0, grid.dirs[0], 0, t) != -1) return 8;
        float prt[256];
        uint32_t v = 0;
        for (; mbpkg_prt_matrix(package, v, prt); v++)
            for (int e = 0; e < 256; e++) printf("%.6f%c", prt[e], e == 255 ? '\n' : ' ');
        printf("%u vertices\n", v);
    }
    mbpkg_close(package);
    return 0;
}
