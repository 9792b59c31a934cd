/*
 * rmannotes_tiles.sl -- decorative tiles built the "RenderMan Notes" way:
 * each pattern element is an opacity layered with blend(), and shapes are
 * made by union, intersection and difference of simpler ones.
 *
 * Exercises: #include "rmannotes.h" (blend, union, intersection,
 * difference, complement, fuzzy pulse, repeat, whichtile, disc,
 * rotate2d and topolar2d statement macros), mod(), atan() with two
 * arguments via topolar2d, cos() petals, cellnoise per tile, and
 * matte lighting.
 */
#include "rmannotes.h"

surface rmannotes_tiles(
    float Ka = 1, Kd = 1;
    float tilefreq = 6, fuzz = .01;
    float groutwidth = .04, petals = 6;
    color basecolor = color(.9, .88, .8);
    color groutcolor = color(.4, .38, .35);
    color flowercolor = color(.15, .3, .6);
    color centercolor = color(.9, .7, .1);)
{
    color surface_color = basecolor;
    color layer_color;
    float layer_opac;

    /* Tile-local coordinates in [0, 1), rotated 45 degrees on odd tiles. */
    float col = whichtile(s, tilefreq), row = whichtile(t, tilefreq);
    float ss = repeat(s, tilefreq), tt = repeat(t, tilefreq);
    float rs, rt;
    float tilerot = (mod(col + row, 2) == 1) ? PI / 4 : 0;
    rotate2d(ss, tt, tilerot, .5, .5, rs, rt);

    /* Grout: the complement of the tile interior in both directions. */
    layer_opac = complement(intersection(pulse(groutwidth, 1 - groutwidth, fuzz, ss),
                                         pulse(groutwidth, 1 - groutwidth, fuzz, tt)));
    surface_color = blend(surface_color, groutcolor, layer_opac);

    /* Flower: petals in polar coordinates about the tile centre. */
    float r, theta;
    topolar2d(rs - .5, rt - .5, r, theta);
    float petalr = .25 + .12 * cos(petals * theta);
    float petal = 1 - smoothstep(petalr - fuzz, petalr, r);

    /* The centre is a disc; cut it out of the petals and colour it apart. */
    float center = disc(rs, rt, .5, .5, .08, fuzz);
    layer_opac = difference(petal, center);
    layer_color = flowercolor * (.8 + .4 * float cellnoise(point(col, row, 0)));
    surface_color = blend(surface_color, layer_color, layer_opac);
    surface_color = blend(surface_color, centercolor, center);

    /* A faint ring where the petals or centre meet the background. */
    float ring = union(pulse(.33, .35, fuzz, r), pulse(.08, .09, fuzz, r));
    surface_color = blend(surface_color, surface_color * .8, ring);

    normal Nf = faceforward(normalize(N), I);
    Oi = Os;
    Ci = Os * surface_color * (Ka * ambient() + Kd * diffuse(Nf));
}
