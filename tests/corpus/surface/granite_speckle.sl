/*
 * granite_speckle.sl -- speckled granite: a hand-written spectral noise sum
 * gives the mineral grains, and cell noise scatters dark flecks.
 *
 * Exercises: a uniform shader parameter used in a loop bound, a for loop
 * with a varying counter and "break" on a varying condition, noise() on a
 * point, cellnoise() returning a colour, filterwidthp(), float arrays as
 * shader parameters with initialisers, array indexing by the loop
 * counter, the ?: operator, color() typecasts and MaterialPlastic.
 */
#include "filterwidth.h"
#include "material.h"

surface granite_speckle(
    float Ka = 1, Kd = .8, Ks = .3, roughness = .15;
    float freq = 12;
    uniform float octaves = 5;
    uniform float octaveweights[5] = {1, .6, .4, .25, .15};
    color graincolor = color(.55, .52, .50);
    color fleckcolor = color(.08, .07, .07);
    float fleckdensity = .12;)
{
    point PP = transform("shader", P) * freq;
    float fw = filterwidthp(PP);
    normal Nf = faceforward(normalize(N), I);
    float sum = 0, weight = 0;
    float f = 1;
    float i;

    /* Sum octaves (at most five) until they become smaller than the pixel. */
    for (i = 0; i < min(octaves, 5); i += 1) {
        if (fw * f > .5)
            break;
        sum += octaveweights[i] * abs(.5 - noise(PP * f));
        weight += octaveweights[i];
        f *= 2.17;
    }
    float grain = (weight > 0) ? sum / weight : .25;

    /* Mineral colour: each cell gets its own slight tint. */
    color tint = color cellnoise(PP * .5);
    color Cg = graincolor * (.75 + grain) * (color(.9) + .2 * tint);

    /* Dark flecks: a random subset of the cells. */
    float fleck = float cellnoise(PP * 1.3 + 17);
    Cg = (fleck < fleckdensity) ? mix(Cg, fleckcolor, .85) : Cg;

    Oi = Os;
    Ci = Os * MaterialPlastic(Nf, Cg, Ka, Kd, Ks, roughness);
}
