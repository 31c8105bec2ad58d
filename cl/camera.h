/* The pinhole camera of scenes/FORMAT.md. */
#ifndef CAMERA_H
#define CAMERA_H

#include "common.h"

/* Direction through continuous image position (x right, y down, in pixels). */
HELPER float3 camera_direction(const Camera* cam, float x, float y) {
    float sx = 2.0f * x / (float)cam->width - 1.0f;
    float sy = 1.0f - 2.0f * y / (float)cam->height;
    return normalize(cam->forward.xyz + sx * cam->right.xyz + sy * cam->up.xyz);
}

/* The image's pixel count: a pass's sample ids 0 .. pixels - 1 are one sample of every pixel. */
HELPER int camera_pixels(const Camera* cam) { return cam->width * cam->height; }

/* Sample `id` of a pass over an image of `pixels` pixels: consecutive ids are consecutive pixels
 * (so samples started together trace coherent primary rays), then the next sample of every pixel.
 * (BDPT's kernels have the pixel count in their pass record, not the camera: bdpt_sampler.) */
HELPER int pixel_of_sample(int pixels, int id) { return id % pixels; }
HELPER int number_of_sample(int pixels, int id, int sample_base) { return sample_base + id / pixels; }
HELPER int sample_pixel(const Camera* cam, int id) { return pixel_of_sample(camera_pixels(cam), id); }
HELPER int sample_number(const Camera* cam, int id, int sample_base) {
    return number_of_sample(camera_pixels(cam), id, sample_base);
}

/* The camera sample: the direction through a box-filtered position (u, v in [0, 1)) inside
 * `pixel` (FORMAT.md). Path tracers and BDPT draw u, v from the same two dimensions. */
HELPER float3 camera_sample(const Camera* cam, int pixel, float u, float v) {
    float x = (float)(pixel % cam->width) + u;
    float y = (float)(pixel / cam->width) + v;
    return camera_direction(cam, x, y);
}

#endif
