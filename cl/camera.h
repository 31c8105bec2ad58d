/* The pinhole camera of scenes/FORMAT.md. */
#ifndef CAMERA_H
#define CAMERA_H

#include "common.h"

/* Direction through continuous image position (x right, y down, in pixels). */
inline float3 camera_direction(const Camera* cam, float x, float y) {
    float sx = 2.0f * x / (float)cam->width - 1.0f;
    float sy = 1.0f - 2.0f * y / (float)cam->height;
    return normalize(cam->forward.xyz + sx * cam->right.xyz + sy * cam->up.xyz);
}

#endif
