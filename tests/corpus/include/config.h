/*
 * config.h -- constants and small utility macros shared by the corpus.
 *
 * Exercises: include guards, object-like macros, function-like macros with
 * several arguments, #if / #elif / #else with defined() and integer
 * arithmetic, macros that expand to other macros, #undef, stringification
 * (#x) and token pasting (a##b).
 */
#ifndef CONFIG_H
#define CONFIG_H

#ifndef PI
#define PI 3.14159265358979323846
#endif
#define TWOPI (2 * PI)
#define HALFPI (PI / 2)

/*
 * Quality level: 0 = draft, 1 = normal, 2 = final.  A shader may define
 * QUALITY before including this file; FORCE_MEDIUM overrides draft.
 */
#ifndef QUALITY
#define QUALITY 1
#endif

#if (QUALITY + 1) * 2 >= 6
#define DEFAULT_OCTAVES 8
#define DEFAULT_SAMPLES 64
#elif QUALITY == 1 || defined(FORCE_MEDIUM)
#define DEFAULT_OCTAVES 6
#define DEFAULT_SAMPLES 16
#else
#define DEFAULT_OCTAVES 3
#define DEFAULT_SAMPLES 4
#endif

/* Arithmetic helpers.  Arguments are parenthesised so expressions work. */
#define SQR(x) ((x) * (x))
#define LERP(t, a, b) ((a) + (t) * ((b) - (a)))
#define CLAMP01(x) clamp((x), 0, 1)
#define LUMINANCE(c) (0.2126 * comp((c), 0) + 0.7152 * comp((c), 1) + 0.0722 * comp((c), 2))
#define DESATURATE(c, amt) mix((c), color(LUMINANCE(c)), (amt))

/* Token pasting: COMPONENT(x, v) becomes xcomp(v). */
#define COMPONENT(axis, v) axis##comp(v)
/* Token pasting that builds a name from two parts: LAYERPARAM(Kd, top) is Kd_top. */
#define LAYERPARAM(name, layer) name##_##layer

/* Stringification: print an expression together with its own source text. */
#define SHOWFLOAT(x) printf("%s = %f\n", #x, (x))
#define SHOWCOLOR(x) printf("%s = %c\n", #x, (x))
#define SHOWPOINT(x) printf("%s = %p\n", #x, (x))

/* A scratch macro used only while this header is read. */
#define CONFIG_SCRATCH 1
#if CONFIG_SCRATCH
#define CONFIG_LOADED 1
#endif
#undef CONFIG_SCRATCH

#endif /* CONFIG_H */
