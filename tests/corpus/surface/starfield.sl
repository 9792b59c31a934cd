/*
 * starfield.sl -- a night sky of point-like stars for the inside of a
 * sky sphere: one candidate star per cell of a 3D grid, kept or dropped at
 * random, with a per-star colour temperature and a slight twinkle.
 *
 * Exercises: cellnoise() returning float and vector, random() (new value
 * on each call), color "hsv" (h, s, v) construction, filterwidthp(),
 * normalize(), a point "world" space cast, vtransform to "world",
 * break/continue inside a loop over
 * neighbouring cells, exp(), and an unlit (constant) result.
 */
#include "filterwidth.h"

surface starfield(
    float frequency = 40;
    float density = .3;
    float starsize = .05;
    float intensity = 3;
    float twinkle = .2;
    color skycolor = color(0, 0, .02);)
{
    /* Work on the unit sphere so stars keep their apparent size. */
    vector Dw = normalize(vtransform("world", P - point "world" (0, 0, 0)));
    point Pg = point(xcomp(Dw), ycomp(Dw), zcomp(Dw)) * frequency;
    float fw = filterwidthp(Pg);
    float i, bright = 0;
    color Cstars = 0;

    /* Look at this cell and the one to its lower left, for stars near edges. */
    for (i = 0; i < 2; i += 1) {
        point cell = point(floor(xcomp(Pg)) - i, floor(ycomp(Pg)) - i, floor(zcomp(Pg)));
        float keep = float cellnoise(cell);
        if (keep > density)
            continue;

        point starpos = cell + vector cellnoise(cell + 31);
        float d = distance(Pg, starpos);
        if (d > 4 * starsize + fw)
            continue;

        /* Gaussian dot whose width never falls below the filter width. */
        float w = max(starsize, fw);
        bright = exp(-(d * d) / (w * w)) * (starsize * starsize) / (w * w);

        /* Colour temperature: bluish to orange, mostly white. */
        float hue = mix(.6, .08, float cellnoise(cell + 7));
        color starcol = color "hsv" (hue, .25 * keep / density, 1);

        Cstars += intensity * bright * starcol * (1 - twinkle + twinkle * random());
        if (bright > .99)
            break;
    }

    Oi = 1;
    Ci = skycolor + Cstars;
}
