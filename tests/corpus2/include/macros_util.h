/*
 * macros_util.h -- statement-producing and multi-line macros, feature
 * toggles and numeric #if chains, shared by several corpus2 shaders.
 *
 * Exercises: an include guard, macros that expand to braced statements
 * (SWAP, SORT3), nested macro calls (SORT3 -> SORT2 -> SWAP), backslash
 * continuations, a macro that expands to a whole illuminance loop,
 * token pasting for parameter names, stringification, #if/#elif/#else
 * on arithmetic over macros, #ifdef/#ifndef toggles, #undef.
 */
#ifndef MACROS_UTIL_H
#define MACROS_UTIL_H

#ifndef PI
#define PI 3.14159265358979
#endif

/* Statement macros: always braced, so they are safe after an if. */
#define SWAP(a, b) { float _t = a; a = b; b = _t; }
#define SWAPC(a, b) { color _tc = a; a = b; b = _tc; }
#define SORT2(a, b) if (a > b) SWAP(a, b)
#define SORT3(a, b, c) { SORT2(a, b); SORT2(b, c); SORT2(a, b); }

/* Expression macros, nested. */
#define SQR(x) ((x) * (x))
#define LENSQ(v) (SQR(xcomp(v)) + SQR(ycomp(v)) + SQR(zcomp(v)))
#define LERP(t, a, b) ((a) + (t) * ((b) - (a)))
#define BIAS(b, x) pow((x), log(b) / log(0.5))
#define GAIN(g, x) \
    (((x) < 0.5) ? BIAS(1 - (g), 2 * (x)) / 2 \
                 : 1 - BIAS(1 - (g), 2 - 2 * (x)) / 2)
#define LUMA(c) (0.299 * comp(c, 0) + 0.587 * comp(c, 1) + 0.114 * comp(c, 2))

/* A macro that produces a complete diffuse light loop into `result`. */
#define ACCUM_DIFFUSE(result, pos, nrm) \
    illuminance(pos, nrm, PI / 2) { \
        float _nd = 0; \
        lightsource("__nondiffuse", _nd); \
        result += (1 - _nd) * Cl * (normalize(L) . nrm); \
    }

/* Token pasting: declare a layer's parameters from its index. */
#define LAYER_PARAMS(n, defcolor) \
    float Kd_##n = 1; \
    color color_##n = defcolor; \
    float freq_##n = 4 * n

/* Stringification for debugging prints. */
#define TRACEVAL(fmt, x) { printf("%s = ", #x); printf(fmt, x); }

/* Quality ladder on a numeric macro. */
#ifndef SHADING_QUALITY
#define SHADING_QUALITY 2
#endif

#if SHADING_QUALITY * 2 > 5
#define NSAMPLES 64
#define NOCTAVES 8
#elif SHADING_QUALITY == 2
#define NSAMPLES 16
#define NOCTAVES 6
#elif SHADING_QUALITY == 1
#define NSAMPLES 4
#define NOCTAVES 4
#else
#define NSAMPLES 1
#define NOCTAVES 2
#endif

/* Feature toggles: define USE_FANCY_SPEC before including to switch models. */
#ifdef USE_FANCY_SPEC
#define SPECFUNC(Nn, V, r) specular_glossy(Nn, V, r, 0.5)
#else
#define SPECFUNC(Nn, V, r) specular(Nn, V, r)
#endif

#endif /* MACROS_UTIL_H */
