/*
 * toon_bands.sl -- cartoon ("cel") shading: lighting quantised into a few
 * flat bands, a hard-edged highlight, a rim light and a dark outline at
 * silhouettes.
 *
 * Exercises: illuminance with a category string excluding lights
 * ("-specular"), illuminance restricted to a category ("rim"), the
 * lightsource("__nonspecular") message, floor() quantisation, step(),
 * the ?: operator on colours, && in conditions, float array parameter
 * with an initialiser indexed by a computed band number, and an output
 * shader parameter.
 */
#include "config.h"

surface toon_bands(
    float Ka = .2, Kd = 1, Ks = 1;
    float bands = 3;
    float bandlevels[4] = {.25, .5, .8, 1};
    float shininess = 40, specthreshold = .5;
    float outlinewidth = .25;
    float rimstrength = .6;
    color inkcolor = color(.05, .03, .08);
    color rimcolor = color(.7, .8, 1);
    output varying float outline = 0;)
{
    normal Nf = faceforward(normalize(N), I);
    vector V = -normalize(I);
    float lit = 0, hilite = 0, rim = 0;

    /* Diffuse bands from every light not reserved for highlights. */
    illuminance("-specular", P, Nf, PI / 2) {
        float ndotl = normalize(L) . Nf;
        float band = clamp(floor(ndotl * bands), 0, 3);
        float luma = LUMINANCE(Cl);
        lit += bandlevels[band] * luma;
    }

    /* A hard-edged highlight, skipping lights that ask not to make one. */
    illuminance(P, Nf, PI / 2) {
        float nonspec = 0;
        lightsource("__nonspecular", nonspec);
        vector H = normalize(normalize(L) + V);
        float sp = pow(max(0, Nf . H), shininess);
        if (nonspec < 1 && sp > specthreshold)
            hilite += 1 - nonspec;
    }

    /* Rim lights only light the edge of the silhouette. */
    illuminance("rim", P) {
        rim += LUMINANCE(Cl) * smoothstep(.5, .9, 1 - (Nf . V));
    }

    /* Ink where the surface turns away from the eye. */
    outline = ((Nf . V) < outlinewidth) ? 1 : 0;

    color Cflat = Cs * (Ka + Kd * lit) + Ks * step(.5, hilite) + rimstrength * rim * rimcolor;
    Oi = Os;
    Ci = Os * ((outline > 0) ? inkcolor : Cflat);
}
