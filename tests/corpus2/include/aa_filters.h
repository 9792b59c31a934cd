/*
 * aa_filters.h -- analytic antialiasing helpers: filter-width estimates
 * built from Du/Dv/du/dv and area(), box-filtered step, pulse, pulse
 * train and checkerboard, in the style of the Advanced RenderMan
 * "filterwidth" idiom.
 *
 * Exercises: include guard with a valued #define, function-like macros
 * expanding to other macros, macros taking expressions as arguments,
 * multi-line macros with backslash continuation, functions built on
 * floor()/mod()/min()/max(), and a header that is meant to be included
 * more than once through different paths.
 */
#ifndef AA_FILTERS_H
#define AA_FILTERS_H 1

#ifndef MINFILTWIDTH
#define MINFILTWIDTH 1.0e-6
#endif

/* Filter width of a float: how much x changes over one sample. */
#define filterwidth(x) max(abs(Du(x) * du) + abs(Dv(x) * dv), MINFILTWIDTH)

/* Filter width of a point-valued quantity, from the area it sweeps. */
#define filterwidthp(p) max(sqrt(area(p)), MINFILTWIDTH)

/* Same, but never wider than a clamp value (avoid washing out at grazing angles). */
#define clampedfilterwidth(x, maxw) min(filterwidth(x), (maxw))

/* The integral of a unit-period pulse train that is 1 on [e, 1). */
#define PULSEINT(x, e) \
    ((1 - (e)) * floor(x) + max(0, (x) - floor(x) - (e)))

/* Integral of a unit-period square wave that is 1 on [0, .5). */
#define SQUAREINT(x) \
    (floor((x) / 2) + 2 * max(0, (x) / 2 - floor((x) / 2) - 0.5))

/* Box-filtered step: 0 below edge, 1 above, linear ramp across the box. */
float boxstep(float edge, x, fw)
{
    return clamp((x - edge) / fw + 0.5, 0, 1);
}

/* Box-filtered pulse: 1 on [edge0, edge1), 0 elsewhere. */
float filteredpulse(float edge0, edge1, x, fw)
{
    float lo = x - fw / 2;
    float hi = lo + fw;
    return max(0, (min(hi, edge1) - max(lo, edge0)) / fw);
}

/*
 * Box-filtered pulse train: 0 on [0, edge) and 1 on [edge, period) in
 * every period.
 */
float filteredpulsetrain(float edge, period, x, fw)
{
    float w = fw / period;
    float x0 = x / period - w / 2;
    float x1 = x0 + w;
    float e = edge / period;
    return (PULSEINT(x1, e) - PULSEINT(x0, e)) / w;
}

/* Box-filtered unit checkerboard in (ss, tt): 0 or 1, grey when filtered away. */
float filteredchecker(float ss, tt, fws, fwt)
{
    float s0 = ss - fws / 2, s1 = ss + fws / 2;
    float t0 = tt - fwt / 2, t1 = tt + fwt / 2;
    float is = (SQUAREINT(2 * s1) - SQUAREINT(2 * s0)) / (2 * fws);
    float it = (SQUAREINT(2 * t1) - SQUAREINT(2 * t0)) / (2 * fwt);
    /* XOR of the two square waves, in expectation */
    return is * (1 - it) + it * (1 - is);
}

/* abs() filtered over a box: the integral of |x| is x*|x|/2. */
float filteredabs(float x, fw)
{
    float x0 = x - fw / 2;
    float x1 = x + fw / 2;
    return (x1 * abs(x1) - x0 * abs(x0)) / (2 * fw);
}

#endif /* AA_FILTERS_H */
