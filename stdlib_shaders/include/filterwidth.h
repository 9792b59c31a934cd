/*
 * filterwidth.h -- rtsl's standard header: how much a value changes
 * across one shading sample, for antialiasing patterns by their own
 * filter width.  The names and meanings are those shader collections
 * expect (Apodaca and Gritz, "Advanced RenderMan", chapter 11); the
 * definitions are this library's own.
 *
 *   filterwidth(x)    the change of float x across a sample: |Du(x) du| +
 *                     |Dv(x) dv|, at least MINFILTWIDTH.
 *   filterwidthp(p)   the same for a point: the square root of the area
 *                     its sample covers, at least MINFILTWIDTH.
 *   filterwidthv(v)   the same for a vector.
 *   fadeout(g, g_avg, featuresize, fwidth)
 *                     g, blended towards its average g_avg as the filter
 *                     width grows past the size of the feature.
 */
#ifndef FILTERWIDTH_H
#define FILTERWIDTH_H 1

#ifndef MINFILTWIDTH
#define MINFILTWIDTH 1.0e-6
#endif

#define filterwidth(x) max(abs(Du(x) * du) + abs(Dv(x) * dv), MINFILTWIDTH)
#define filterwidthp(p) max(sqrt(area(p)), MINFILTWIDTH)
#define filterwidthv(v) max(length(Du(v) * du) + length(Dv(v) * dv), MINFILTWIDTH)

#define fadeout(g, g_avg, featuresize, fwidth) \
    mix(g, g_avg, smoothstep(0.2, 0.6, (fwidth) / (featuresize)))

#endif
