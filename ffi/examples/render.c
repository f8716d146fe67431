/*
 * Renders a scene through the Nimbus C API and checks the result.
 *
 *   render SCENE [WIDTH HEIGHT SPP [OUTPUT.exr]]
 *
 * Loads SCENE (.gltf, .glb, .obj or a USD stage), renders it (default 16x16 at 1 spp), checks that every beauty sample is
 * finite and that some are non-zero, and, given OUTPUT.exr, writes the EXR and a PNG preview beside it.
 * Exits 0 on success, 1 on any failure (with the library's message on stderr).
 *
 * Build (from the repository root, after `cargo build -p nimbus-ffi`):
 *   cc -std=c99 -Iffi/include ffi/examples/render.c -Ltarget/debug -lnimbus_c -o render
 *   LD_LIBRARY_PATH=target/debug ./render assets/demo.glb
 */
#include "nimbus.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Reports a failed call and says whether it failed. */
static int failed(NimbusStatus status, const char *what) {
    if (status == NIMBUS_STATUS_OK) {
        return 0;
    }
    fprintf(stderr, "render: %s failed (status %d): %s\n", what, (int)status, nimbus_last_error());
    return 1;
}

/* Progress callback: counts the passes and prints the progress; never cancels. */
static int on_progress(float fraction, uint32_t spp, void *user_data) {
    int *passes = (int *)user_data;
    *passes += 1;
    fprintf(stderr, "render: %3.0f%% (%u spp)\n", fraction * 100.0f, spp);
    return 1;
}

int main(int argc, char **argv) {
    if (argc != 2 && argc != 5 && argc != 6) {
        fprintf(stderr, "usage: %s SCENE [WIDTH HEIGHT SPP [OUTPUT.exr]]\n", argv[0]);
        return 1;
    }
    NimbusRenderSettings settings = nimbus_render_settings_default();
    settings.width = 16;
    settings.height = 16;
    settings.spp = 1;
    if (argc >= 5) {
        settings.width = (uint32_t)strtoul(argv[2], NULL, 10);
        settings.height = (uint32_t)strtoul(argv[3], NULL, 10);
        settings.spp = (uint32_t)strtoul(argv[4], NULL, 10);
    }

    int status = 1;
    NimbusScene *scene = NULL;
    NimbusImage *image = NULL;
    float *red = NULL;
    int passes = 0;
    if (failed(nimbus_scene_load(argv[1], &scene), "nimbus_scene_load")) {
        goto done;
    }
    if (failed(nimbus_render(scene, &settings, on_progress, &passes, &image), "nimbus_render")) {
        goto done;
    }
    /* The image does not borrow from the scene. */
    if (failed(nimbus_scene_free(&scene), "nimbus_scene_free")) {
        goto done;
    }

    uint32_t width = 0, height = 0;
    if (failed(nimbus_image_width(image, &width), "nimbus_image_width") ||
        failed(nimbus_image_height(image, &height), "nimbus_image_height")) {
        goto done;
    }
    if (width != settings.width || height != settings.height || passes < 1) {
        fprintf(stderr, "render: got %ux%u after %d progress calls, asked for %ux%u\n", width, height,
                passes, settings.width, settings.height);
        goto done;
    }
    size_t n = (size_t)width * height;
    red = malloc(n * sizeof(float));
    if (red == NULL) {
        fprintf(stderr, "render: out of memory\n");
        goto done;
    }
    const char *channels[] = {"R", "G", "B"};
    double sum = 0.0;
    for (int c = 0; c < 3; c++) {
        if (failed(nimbus_image_channel(image, channels[c], red, n), "nimbus_image_channel")) {
            goto done;
        }
        for (size_t i = 0; i < n; i++) {
            if (!isfinite(red[i]) || red[i] < 0.0f) {
                fprintf(stderr, "render: channel %s pixel %zu is %g\n", channels[c], i, red[i]);
                goto done;
            }
            sum += red[i];
        }
    }
    if (!(sum > 0.0)) {
        fprintf(stderr, "render: the image is black\n");
        goto done;
    }
    if (argc == 6) {
        char png[4096];
        size_t len = strlen(argv[5]);
        if (len < 4 || len >= sizeof png) {
            fprintf(stderr, "render: output path must end in .exr\n");
            goto done;
        }
        memcpy(png, argv[5], len - 4);
        strcpy(png + len - 4, ".png");
        if (failed(nimbus_image_write_exr(image, argv[5]), "nimbus_image_write_exr") ||
            failed(nimbus_image_write_png(image, png, 0.0f), "nimbus_image_write_png")) {
            goto done;
        }
    }
    printf("render: %ux%u, mean %.6g, %d passes\n", width, height, sum / (3.0 * (double)n), passes);
    status = 0;

done:
    free(red);
    /* Free functions null the pointer and accept NULL, so this is safe on every path. */
    nimbus_image_free(&image);
    nimbus_scene_free(&scene);
    return status;
}
