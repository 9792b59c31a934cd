/*
 * ocean_waves.sl -- open-ocean displacement: a sum of directional
 * travelling waves given in parallel array parameters, sharpened at the
 * crests (Gerstner-like), animated with the shutter time, plus fine
 * noise chop.
 *
 * Exercises: uniform float array parameters with initialisers, a uniform
 * for loop over them, sin()/cos() of a phase built from a dot product,
 * vector arithmetic with a horizontal displacement, transform() and
 * vtransform() between "current" and "world", time, noise chop, an
 * output parameter carrying the crest foam amount, and calculatenormal().
 */
#include "config.h"

displacement ocean_waves(
    float Km = 1;
    uniform float nwaves = 4;
    uniform float amplitudes[4] = {.3, .15, .08, .04};
    uniform float wavelengths[4] = {12, 5.5, 2.7, 1.1};
    uniform float directions[4] = {0, 30, -25, 70};
    float choppiness = .6;
    float chop = .02;
    output varying float foam = 0;)
{
    point Pw = transform("world", P);
    vector disp = 0;
    float crest = 0;
    uniform float i;

    for (i = 0; i < min(nwaves, 4); i += 1) {
        uniform float k = TWOPI / wavelengths[i];
        uniform float speed = sqrt(9.81 / k);
        uniform vector D = vector(cos(radians(directions[i])), 0, sin(radians(directions[i])));
        float phase = k * (D . vector(xcomp(Pw), 0, zcomp(Pw))) - k * speed * time;

        /* Vertical heave plus horizontal pinching toward the crests. */
        disp += vector(0, amplitudes[i] * sin(phase), 0);
        disp -= choppiness * amplitudes[i] * cos(phase) * D;
        crest += amplitudes[i] * sin(phase);
    }

    disp += vector(0, chop * (noise(Pw * 3 + vector(0, time, 0)) - .5), 0);
    foam = smoothstep(.25, .45, crest);

    P += Km * vtransform("world", "current", disp);
    N = calculatenormal(P);
}
