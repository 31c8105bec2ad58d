/* OpenCL built-ins written out, where the compiler leaves them as calls (PoCL 3.0: the host
 * defines BUILTINS_ARE_CALLS there, toolkit/opencl/program.py). PoCL links its built-in library
 * after optimising the kernel, so dot, normalize, sqrt, fabs, ... each stayed a function call:
 * in perf, 20% of pt_naive_render's time was spent inside them (normalize alone 8%), besides
 * the calls themselves. Here the ones the kernels use are always-inline overloads, and OpenCL's
 * names are mapped to them, so every kernel still writes dot(a, b). Other compilers inline their
 * own built-ins and keep them. Same definitions as OpenCL's (sqrt correctly rounded, fmin/fmax
 * return the other operand where one is NaN); normalize skips the rescaling that guards vectors
 * whose squared length under- or overflows float32, which no scene here comes near
 * (coordinates are relative to the scene's centre, scene.h). */
#ifndef INLINE_BUILTINS_H
#define INLINE_BUILTINS_H

#if BUILTINS_ARE_CALLS

/* Helpers (HELPER, common.h) that overload one name for several argument types, as OpenCL's do. */
#define OVERLOADED __attribute__((overloadable))

/* Clang's own built-ins become single instructions (LLVM intrinsics), not library calls. */
HELPER OVERLOADED float inline_sqrt(float x) { return __builtin_sqrtf(x); }
HELPER OVERLOADED float inline_rsqrt(float x) { return 1.0f / __builtin_sqrtf(x); }
HELPER OVERLOADED float inline_fabs(float x) { return __builtin_fabsf(x); }
HELPER OVERLOADED float inline_fmin(float a, float b) { return __builtin_fminf(a, b); }
HELPER OVERLOADED float inline_fmax(float a, float b) { return __builtin_fmaxf(a, b); }
HELPER OVERLOADED float3 inline_fmin(float3 a, float3 b) {
    return (float3)(__builtin_fminf(a.x, b.x), __builtin_fminf(a.y, b.y), __builtin_fminf(a.z, b.z));
}
HELPER OVERLOADED float3 inline_fmax(float3 a, float3 b) {
    return (float3)(__builtin_fmaxf(a.x, b.x), __builtin_fmaxf(a.y, b.y), __builtin_fmaxf(a.z, b.z));
}
HELPER OVERLOADED float inline_copysign(float a, float b) { return __builtin_copysignf(a, b); }
HELPER OVERLOADED int inline_isfinite(float x) { return __builtin_isfinite(x); }

HELPER OVERLOADED float inline_dot(float2 a, float2 b) { return a.x * b.x + a.y * b.y; }
HELPER OVERLOADED float inline_dot(float3 a, float3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
HELPER OVERLOADED float3 inline_cross(float3 a, float3 b) {
    return (float3)(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
HELPER OVERLOADED float inline_length(float3 v) { return __builtin_sqrtf(inline_dot(v, v)); }
/* A zero vector stays zero, as OpenCL's normalize returns it. */
HELPER OVERLOADED float3 inline_normalize(float3 v) {
    float l2 = inline_dot(v, v);
    return l2 > 0.0f ? v * (1.0f / __builtin_sqrtf(l2)) : v;
}
/* vstore8 into a private array: one unaligned store. */
HELPER OVERLOADED void inline_vstore8(float8 v, size_t offset, __private float* p) {
    __builtin_memcpy(p + 8 * offset, &v, sizeof v);
}
HELPER OVERLOADED void inline_vstore8(int8 v, size_t offset, __private int* p) {
    __builtin_memcpy(p + 8 * offset, &v, sizeof v);
}

/* The other argument types OpenCL allows for these names (float2/float4 vectors, and fmin/fmax of a
 * vector and a scalar): no kernel here uses them today, but a student's file may, and a name
 * mapped below with no overload for its types would not compile on PoCL alone. */
HELPER OVERLOADED float2 inline_fmin(float2 a, float2 b) { return (float2)(__builtin_fminf(a.x, b.x), __builtin_fminf(a.y, b.y)); }
HELPER OVERLOADED float2 inline_fmax(float2 a, float2 b) { return (float2)(__builtin_fmaxf(a.x, b.x), __builtin_fmaxf(a.y, b.y)); }
HELPER OVERLOADED float4 inline_fmin(float4 a, float4 b) { return (float4)(inline_fmin(a.xy, b.xy), inline_fmin(a.zw, b.zw)); }
HELPER OVERLOADED float4 inline_fmax(float4 a, float4 b) { return (float4)(inline_fmax(a.xy, b.xy), inline_fmax(a.zw, b.zw)); }
HELPER OVERLOADED float2 inline_fmin(float2 a, float b) { return inline_fmin(a, (float2)(b)); }
HELPER OVERLOADED float2 inline_fmax(float2 a, float b) { return inline_fmax(a, (float2)(b)); }
HELPER OVERLOADED float3 inline_fmin(float3 a, float b) { return inline_fmin(a, (float3)(b)); }
HELPER OVERLOADED float3 inline_fmax(float3 a, float b) { return inline_fmax(a, (float3)(b)); }
HELPER OVERLOADED float4 inline_fmin(float4 a, float b) { return inline_fmin(a, (float4)(b)); }
HELPER OVERLOADED float4 inline_fmax(float4 a, float b) { return inline_fmax(a, (float4)(b)); }
HELPER OVERLOADED float2 inline_fabs(float2 v) { return (float2)(__builtin_fabsf(v.x), __builtin_fabsf(v.y)); }
HELPER OVERLOADED float3 inline_fabs(float3 v) { return (float3)(inline_fabs(v.xy), __builtin_fabsf(v.z)); }
HELPER OVERLOADED float4 inline_fabs(float4 v) { return (float4)(inline_fabs(v.xy), inline_fabs(v.zw)); }
HELPER OVERLOADED float2 inline_sqrt(float2 v) { return (float2)(__builtin_sqrtf(v.x), __builtin_sqrtf(v.y)); }
HELPER OVERLOADED float3 inline_sqrt(float3 v) { return (float3)(inline_sqrt(v.xy), __builtin_sqrtf(v.z)); }
HELPER OVERLOADED float4 inline_sqrt(float4 v) { return (float4)(inline_sqrt(v.xy), inline_sqrt(v.zw)); }
HELPER OVERLOADED float inline_dot(float a, float b) { return a * b; }
HELPER OVERLOADED float inline_dot(float4 a, float4 b) { return a.x * b.x + a.y * b.y + a.z * b.z + a.w * b.w; }
HELPER OVERLOADED float4 inline_cross(float4 a, float4 b) { return (float4)(inline_cross(a.xyz, b.xyz), 0.0f); }
HELPER OVERLOADED float inline_length(float v) { return __builtin_fabsf(v); }
HELPER OVERLOADED float inline_length(float2 v) { return __builtin_sqrtf(inline_dot(v, v)); }
HELPER OVERLOADED float inline_length(float4 v) { return __builtin_sqrtf(inline_dot(v, v)); }
HELPER OVERLOADED float2 inline_normalize(float2 v) {
    float l2 = inline_dot(v, v);
    return l2 > 0.0f ? v * (1.0f / __builtin_sqrtf(l2)) : v;
}
HELPER OVERLOADED float4 inline_normalize(float4 v) {
    float l2 = inline_dot(v, v);
    return l2 > 0.0f ? v * (1.0f / __builtin_sqrtf(l2)) : v;
}

/* PoCL's header maps these names to its library by object-like macros; ours are function-like,
 * so a record field of the same name (ShadowRay.length) is left alone. */
#undef sqrt
#define sqrt(x) inline_sqrt(x)
#undef rsqrt
#define rsqrt(x) inline_rsqrt(x)
#undef fabs
#define fabs(x) inline_fabs(x)
#undef fmin
#define fmin(a, b) inline_fmin(a, b)
#undef fmax
#define fmax(a, b) inline_fmax(a, b)
#undef copysign
#define copysign(a, b) inline_copysign(a, b)
#undef isfinite
#define isfinite(x) inline_isfinite(x)
#undef dot
#define dot(a, b) inline_dot(a, b)
#undef cross
#define cross(a, b) inline_cross(a, b)
#undef length
#define length(v) inline_length(v)
#undef normalize
#define normalize(v) inline_normalize(v)
#undef vstore8
#define vstore8(v, offset, p) inline_vstore8(v, offset, p)

#endif /* BUILTINS_ARE_CALLS */

#endif
