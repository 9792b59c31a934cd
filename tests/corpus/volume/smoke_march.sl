/*
 * smoke_march.sl -- lit smoke in the manner of ray-marching atmosphere
 * shaders: density from turbulence, in-scattered light gathered at each
 * step with an illuminance loop, and the step size jittered to trade
 * banding for noise.
 *
 * Exercises: a volume shader using illuminance(point) (whole sphere) at
 * points along the ray, a while loop with a varying bound, random() for
 * jitter, turbulence() from noises.h, transform() into "shader"
 * space, colour accumulation with += and *=, and exp() attenuation.
 */
#include "noises.h"

volume smoke_march(
    float density = 1;
    float integstart = 0, integend = 100;
    float stepsize = .1;
    float smokefreq = 1, smokeoctaves = 3;
    float lightscale = 1;
    color smokecolor = 1;
    float usejitter = 1;)
{
    /* March front to back, from the eye end of the segment towards P. */
    point Pstart = P - I;
    float raylen = length(I);
    vector dir = I / max(raylen, 1.0e-6);
    float tend = min(raylen, integend);
    float tpos = integstart;
    color Cv = 0, Ov = 0;

    if (usejitter > 0)
        tpos += stepsize * random();

    while (tpos < tend) {
        point Pcur = Pstart + tpos * dir;
        point Psh = transform("shader", Pcur) * smokefreq;
        float dens = density * max(0, turbulence(Psh, smokeoctaves, 2, .5) - .2);

        if (dens > 0) {
            /* Light arriving at this point from every direction. */
            color li = 0;
            illuminance(Pcur) {
                li += Cl;
            }
            color opac = 1 - exp(-dens * stepsize);
            Cv += (1 - Ov) * opac * smokecolor * lightscale * li;
            Ov += (1 - Ov) * opac;
        }
        tpos += stepsize;
    }

    Ci = Cv + (1 - Ov) * Ci;
    Oi = Ov + (1 - Ov) * Oi;
}
