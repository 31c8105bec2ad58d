/* What the connection code (bdpt.h) and the MIS weight (mis.h) read off a stored BDPT vertex
 * (BdptVertex and its VERTEX_* flags: toolkit/core/layout.py, in layout.h). Its own header so
 * that mis.h, the file course assignment 4 replaces, compiles without bdpt.h. */
#ifndef BDPT_VERTEX_H
#define BDPT_VERTEX_H

#include "common.h"

HELPER bool is_delta(const BdptVertex* v) { return (v->flags & VERTEX_DELTA) != 0; }
HELPER bool is_camera(const BdptVertex* v) { return (v->flags & VERTEX_CAMERA) != 0; }
HELPER bool is_light_origin(const BdptVertex* v) { return (v->flags & VERTEX_LIGHT) != 0; }

/* A density of 0 (not known, or a delta in pbrt-v3's convention) counts as 1 in the MIS
 * ratios, as pbrt-v3's bdpt.cpp does. */
HELPER float remap0(float f) { return f != 0.0f ? f : 1.0f; }

#endif
