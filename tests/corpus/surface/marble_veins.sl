/*
 * marble_veins.sl -- veined marble: a colour spline indexed by turbulence,
 * with sharp dark veins where a second noise field crosses zero.
 *
 * Exercises: #define of NOISE_OCTAVES before including noises.h (the
 * header's #if caps it), turbulence(), fBm(), a local colour array with an
 * initialiser, spline() with an explicit "catmull-rom" basis over the
 * array, spline() without a basis over listed colours, transform() into
 * "shader" space, filterwidthp(), plastic-style lighting inline, a uniform
 * local, and writing an output varying shader parameter.
 */
#define NOISE_OCTAVES 7
#include "noises.h"

surface marble_veins(
    float Ka = 1, Kd = .8, Ks = .5, roughness = .06;
    float veinfreq = 1.5, veinsharpness = 12, veindepth = .8;
    float turbscale = 2.5;
    color veincolor = color(.15, .12, .14);
    output varying float veinmask = 0;)
{
    color palette[6] = {
        color(.92, .90, .86), color(.92, .90, .86), color(.84, .80, .78),
        color(.78, .74, .74), color(.62, .58, .60), color(.62, .58, .60)
    };
    uniform float veinoctaves = NOISE_OCTAVES;
    point PP = transform("shader", P);
    float fw = filterwidthp(PP);
    normal Nf = faceforward(normalize(N), I);
    vector V = -normalize(I);

    /* Base tone: a turbulent layer pattern running along x. */
    float turb = turbulence(PP * turbscale, veinoctaves, 2, .5);
    float layer = .5 + .5 * sin(4 * (xcomp(PP) + turb));
    color Cbase = color spline("catmull-rom", layer, palette);

    /* Faint secondary clouding, with a basis-less spline. */
    float cloud = .5 + .25 * fBm(PP * 3, 4, 2, .5);
    Cbase *= color spline(clamp(cloud, 0, 1),
                          color(.9, .9, .9), color(.9, .9, .9),
                          color(1, 1, 1), color(1.05, 1.02, 1),
                          color(1.05, 1.02, 1));

    /* Veins: where a noise field is near zero, sharpened, faded when tiny. */
    float vn = abs(snoise(PP * veinfreq + 0.5 * turb));
    float vein = pow(1 - clamp(vn, 0, 1), veinsharpness);
    vein *= 1 - smoothstep(.05, .3, fw * veinfreq * veinsharpness);
    veinmask = vein;

    color Cm = mix(Cbase, veincolor, veindepth * vein);

    Oi = Os;
    Ci = Os * (Cm * (Ka * ambient() + Kd * diffuse(Nf))
               + Ks * specular(Nf, V, roughness));
}
