/*
 * rmannotes.h -- layering and pattern-building macros in the style of
 * the "RenderMan Notes" tutorials: patterns are computed as opacities in
 * [0, 1] and layered with blend(); shapes are combined with set operations
 * on those opacities.
 *
 * Exercises: include guards, #ifdef with an #error in an inactive branch,
 * many multi-argument function-like macros, a statement macro with line
 * continuations, macros using other macros, #undef.
 */
#ifndef RMANNOTES_H
#define RMANNOTES_H

/* patterns.h defines pulse(), repeat() and whichtile() with other meanings. */
#ifdef PATTERNS_H
#error "rmannotes.h and patterns.h cannot be used in the same shader"
#endif

#ifndef PI
#define PI 3.14159265358979323846
#endif

/* Layer b over a with opacity x. */
#define blend(a, b, x) ((a) * (1 - (x)) + (b) * (x))

/* Set operations on opacities. */
#define union(a, b) ((a) + (b) - (a) * (b))
#define intersection(a, b) ((a) * (b))
#define difference(a, b) ((a) * (1 - (b)))
#define complement(a) (1 - (a))

/* A soft-edged pulse: 1 between a and b, ramping over "fuzz" at each edge. */
#define pulse(a, b, fuzz, x) \
    (smoothstep((a) - (fuzz), (a), (x)) - smoothstep((b) - (fuzz), (b), (x)))

/* Tiling. */
#define repeat(x, freq) (mod((x) * (freq), 1.0))
#define whichtile(x, freq) (floor((x) * (freq)))

/* A disc of the given radius at (cx, cy), soft over "fuzz". */
#define RN_DIST2D(x, y, cx, cy) sqrt(((x) - (cx)) * ((x) - (cx)) + ((y) - (cy)) * ((y) - (cy)))
#define disc(x, y, cx, cy, radius, fuzz) \
    (1 - smoothstep((radius) - (fuzz), (radius), RN_DIST2D(x, y, cx, cy)))

/* Rotation and polar coordinates in the (s, t) plane. */
#define rotate2d(x, y, rad, ox, oy, rx, ry) \
    rx = ((x) - (ox)) * cos(rad) - ((y) - (oy)) * sin(rad) + (ox); \
    ry = ((x) - (ox)) * sin(rad) + ((y) - (oy)) * cos(rad) + (oy)

#define topolar2d(x, y, r, theta) \
    r = sqrt((x) * (x) + (y) * (y)); \
    theta = atan((y), (x))

#endif /* RMANNOTES_H */
