/*
 * wood_grain.sl -- solid-textured wood: concentric growth rings around the
 * shader-space z axis, wobbled by noise, with fine fibre grain on top.
 *
 * Exercises: #include of noises.h and material.h (which pull in config.h
 * and filterwidth.h), transform(space, P) with a string parameter,
 * filterwidthp() (area()) and filterwidth() (Du/Dv) macros, vector-valued
 * signed noise, setzcomp, SQR from config.h, the fadeout() antialiasing
 * idiom, mix() of colours, and MaterialPlastic from material.h.
 */
#include "noises.h"
#include "material.h"

surface wood_grain(
    float Ka = 1, Kd = .75, Ks = .4, roughness = .1;
    color lightwood = color(.69, .44, .25);
    color darkwood = color(.35, .22, .08);
    float ringfreq = 8, ringunevenness = .5;
    float ringnoise = .02, ringnoisefreq = 1;
    float grainfreq = 25, grainy = 1;
    float trunkwobble = .15, trunkwobblefreq = .025;
    float angularwobble = .1, angularwobblefreq = 1.5;
    string shadingspace = "shader";)
{
    point Pshad = transform(shadingspace, P);
    float dPshad = filterwidthp(Pshad);
    normal Nf = faceforward(normalize(N), I);

    /* Bend the trunk axis slowly along its length (the z axis). */
    vector axiswobble = trunkwobble * vsnoise(zcomp(Pshad) * trunkwobblefreq);
    setzcomp(axiswobble, 0);
    point Pw = Pshad + axiswobble;

    /* A little 3D jitter so the rings are not perfect cylinders. */
    Pw += ringnoise * vsnoise(Pw * ringnoisefreq);

    /* Distance from the axis, in rings, with some angular wobble. */
    float r = ringfreq * sqrt(SQR(xcomp(Pw)) + SQR(ycomp(Pw)));
    r += angularwobble * smoothstep(0, 5, r)
         * snoise(angularwobblefreq * point(xcomp(Pw), ycomp(Pw), 0));
    float dr = filterwidth(r);

    /* Uneven ring spacing: perturb the ring index with 1D noise. */
    r += 0.5 * filteredsnoise(r, dr);

    /* Each ring is light early-wood fading into a dark late-wood band. */
    float inring = mod(r, 1);
    float ring = smoothstep(0, .8, inring) - smoothstep(.83, 1, inring);
    ring = pow(ring, 1 + ringunevenness * noise(floor(r)));
    ring = fadeout(ring, .5, 1, dr);

    /* Fibre grain: noise stretched along the trunk, only in the dark wood. */
    point Pgrain = Pw * grainfreq;
    setzcomp(Pgrain, zcomp(Pgrain) * .05);
    float dgrain = dPshad * grainfreq;
    float grain = smoothstep(.55, .8, noise(Pgrain));
    grain = fadeout(grain, .2, 1, dgrain);

    color Cwood = mix(lightwood, darkwood, ring);
    Cwood *= 1 - grainy * .4 * grain * ring;

    Oi = Os;
    Ci = Os * MaterialPlastic(Nf, Cwood, Ka, Kd, Ks * (1 - .5 * ring), roughness);
}
