/*
 * arrays_ramp.sl -- a user-defined colour ramp (like the ramp nodes of
 * interactive packages): positions and colours come in parallel array
 * parameters, and the ramp is evaluated along a chosen direction with
 * linear, smooth or stepped interpolation.
 *
 * Exercises: fixed-size array shader parameters with initialisers,
 * local arrays with and without initialisers (float knots[8] = {...},
 * color colors[4]), element assignment in loops, passing arrays to
 * functions with unsized array parameters (float a[], color c[]) from
 * palettes.h and locally, ArraySum/ArrayFindInterval, spline over a
 * local float array with the "catmull-rom" and "bspline" bases, string
 * switches, and the ?: operator.
 */
#include "palettes.h"

/* Linear interpolation in a ramp of n (position, colour) pairs. */
color RampLinear(float pos[]; color cols[]; float n; float x)
{
    float hi = ArrayFindInterval(pos, n, x);
    if (hi <= 0)
        return cols[0];
    if (hi >= n)
        return cols[n - 1];
    float lo = hi - 1;
    float f = (x - pos[lo]) / max(pos[hi] - pos[lo], 1.0e-6);
    return mix(cols[lo], cols[hi], f);
}

surface arrays_ramp(
    float Ka = 1, Kd = .8;
    uniform float positions[4] = {0, .3, .6, 1};
    color colors[4] = {color(.1, .1, .4), color(.2, .6, .8),
                       color(.9, .9, .6), color(1, .5, .2)};
    string interpolation = "linear";
    string direction = "t";
    float wobble = .05;)
{
    float knots[8] = {0, 0, .1, .35, .6, .9, 1, 1};
    color smoothcols[4];
    float weights[4];
    float x = (direction == "s") ? s : t;
    float i;

    /* Remap x through a spline-shaped contrast curve. */
    x = clamp(x + wobble * (noise(P * 5) - .5), 0, 1);
    x = (interpolation == "bspline") ? spline("bspline", x, knots)
                                     : spline("catmull-rom", x, knots);

    /* Copy the parameter colours into a local array, weighting each. */
    for (i = 0; i < 4; i += 1) {
        weights[i] = 1 + i * .1;
        smoothcols[i] = colors[i] * weights[i];
    }
    float norm = ArraySum(weights, 4) / 4;

    color C;
    if (interpolation == "step")
        C = PaletteStep(smoothcols, 4, x);
    else if (interpolation == "smooth" || interpolation == "bspline")
        C = PaletteSmooth(smoothcols, x);
    else
        C = RampLinear(positions, smoothcols, 4, x);
    C /= norm;

    normal Nf = faceforward(normalize(N), I);
    Oi = Os;
    Ci = Os * C * (Ka * ambient() + Kd * diffuse(Nf));
}
