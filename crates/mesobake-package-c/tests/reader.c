/* A C program that reads a mesobake package through the C ABI: its grids, its sections
 * (with a checksum of their bytes) and the GDM at every voxel of the middle layer along
 * every direction bin. tests/c_program.rs compiles it and compares its output with the Rust
 * reader's. */
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "mesobake_package.h"

int main(int argc, char **argv) {
    if (argc != 2) {
        fprintf(stderr, "usage: reader PACKAGE\n");
        return 2;
    }
    char error[256];
    MbpkgPackage *package = mbpkg_open(argv[1], (uint64_t)1 << 30, error, sizeof error);
    if (package == NULL) {
        printf("error: %s\n", error);
        return 1;
    }
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
    mbpkg_close(package);
    return 0;
}
