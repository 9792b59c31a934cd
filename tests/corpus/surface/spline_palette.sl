/*
 * spline_palette.sl -- a test card of bands, each coloured by a different
 * kind of spline, for checking every basis against a reference renderer.
 * Each band runs a spline from s = 0 to s = 1; t picks the band.
 *
 * Exercises: spline() with every basis string ("catmull-rom", "bspline",
 * "linear", "bezier", "hermite") and with no basis, on floats and on
 * colours, in the knot-list form and the array form spline(x, array) with
 * both a basis and without, local and parameter arrays, PaletteStep and
 * PaletteSmooth (array parameters) and RainbowFill (output array) from
 * palettes.h, and whichtile-style band selection with floor().
 */
#include "palettes.h"

surface spline_palette(
    float bandcount = 8;
    float knots[6] = {0, 0, .3, .9, 1, 1};
    color ramp[5] = {color(0, 0, 0), color(0, 0, .5), color(.9, .2, .1),
                     color(1, .9, .4), color(1, 1, 1)};)
{
    float band = floor(t * bandcount);
    float x = clamp(s, 0, 1);
    float value = 0;
    color C = 0;
    color rainbow[6];

    RainbowFill(rainbow, 6, .8, 1);

    if (band == 0) {
        C = color spline("catmull-rom", x, ramp[0], ramp[0], ramp[1], ramp[2],
                         ramp[3], ramp[4], ramp[4]);
    } else if (band == 1) {
        C = color spline("bspline", x, ramp[0], ramp[0], ramp[2], ramp[4], ramp[4]);
    } else if (band == 2) {
        value = spline("linear", x, 0, 0, 1, .2, 1, 1);
        C = value;
    } else if (band == 3) {
        /* Bezier: 4 + 3n knots. */
        value = spline("bezier", x, 0, 1.2, -.2, 1);
        C = color(value, value * value, 1 - value);
    } else if (band == 4) {
        /* Hermite: value, tangent pairs. */
        value = spline("hermite", x, 0, 2, 1, 0);
        C = color(value);
    } else if (band == 5) {
        value = spline(x, knots);
        C = value * ramp[3];
    } else if (band == 6) {
        C = color spline("linear", x, ramp);
    } else {
        float half = (x < .5) ? 1 : 0;
        C = (half > 0) ? PaletteStep(rainbow, 6, x * 2) : PaletteSmooth(rainbow, x * 2 - 1);
    }

    Oi = Os;
    Ci = Os * C;
}
