/*
 * screen_holes.sl -- a metal window screen: a grid of wires whose gaps are
 * transparent, antialiased so the opacity averages correctly at distance.
 *
 * Exercises: filterwidth(), filteredpulsetrain() from patterns.h, the
 * union() of two coverages written out, Oi set below 1 (partial opacity),
 * MaterialRoughMetal from material.h, varying locals, and the "linear"
 * spline basis used to shape the wire profile.
 */
#include "patterns.h"
#include "material.h"

surface screen_holes(
    float Ka = 1, Ks = .8, roughness = .2;
    float density = .25;
    float frequency = 20;
    color wirecolor = color(.6, .6, .62);)
{
    normal Nf = faceforward(normalize(N), I);
    float ss = s * frequency, tt = t * frequency;
    float sw = filterwidth(ss), tw = filterwidth(tt);

    /* Coverage of the wires running in t and in s. */
    float wire_s = filteredpulsetrain(density, 1, ss, sw);
    float wire_t = filteredpulsetrain(density, 1, tt, tw);

    /* Union of the two sets of wires: a + b - a*b. */
    float coverage = wire_s + wire_t - wire_s * wire_t;

    /* Shade wires a bit darker in their centres, with a linear spline. */
    float across = min(abs(mod(ss, 1) - density / 2), abs(mod(tt, 1) - density / 2));
    float shade = spline("linear", clamp(across / density * 2, 0, 1), .7, .7, 1, 1);

    Oi = coverage * Os;
    Ci = Oi * MaterialRoughMetal(Nf, wirecolor * shade, Ka, Ks, roughness);
}
