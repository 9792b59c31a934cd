/*
 * filterwidth.h -- estimating how much a quantity changes across one
 * shading sample, for analytic antialiasing.
 *
 * Exercises: include guards, macros built from Du/Dv/du/dv, area(),
 * macros that expand to other macros (filterwidthp -> MINFILTWIDTH),
 * multi-argument macros.
 */
#ifndef FILTERWIDTH_H
#define FILTERWIDTH_H

/* Never let a filter width reach zero; we divide by it. */
#define MINFILTWIDTH 1.0e-6

/* Width of a float quantity over the sample, from its parametric derivatives. */
#define filterwidth(x) max(abs(Du(x) * du) + abs(Dv(x) * dv), MINFILTWIDTH)

/* Width of a point quantity: the square root of the area it sweeps. */
#define filterwidthp(p) max(sqrt(area(p)), MINFILTWIDTH)

/* Vector variant: the larger of the per-axis widths. */
#define filterwidthv(v) max(length(Du(v) * du), max(length(Dv(v) * dv), MINFILTWIDTH))

/*
 * Fade a pattern g towards its average value g_avg as the filter width
 * approaches the size of the pattern's smallest feature.
 */
#define fadeout(g, g_avg, featuresize, fwidth) \
    mix((g), (g_avg), smoothstep(.2, .6, (fwidth) / (featuresize)))

#endif /* FILTERWIDTH_H */
