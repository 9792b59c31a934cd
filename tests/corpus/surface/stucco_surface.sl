/*
 * stucco_surface.sl -- surface companion to displacement/stucco_dents.sl:
 * painted stucco whose dents collect dirt.  The dent mask and height are
 * read from the displacement shader by message passing, so the colour
 * always matches the geometry.
 *
 * Exercises: displacement("dentmask", x) and displacement("bumpheight", x)
 * message passing, a fallback computation when the displacement shader
 * does not provide the value, noise(), the Oren-Nayar model from
 * material.h for a rough matte finish, mix(), and smoothstep().
 */
#include "material.h"

surface stucco_surface(
    float Ka = 1, Kd = .9;
    float roughangle = .5;
    float dirt = .6;
    color paintcolor = color(.92, .88, .8);
    color dirtcolor = color(.4, .36, .3);)
{
    float dent = 0, height = 0;
    normal Nf = faceforward(normalize(N), I);
    vector V = -normalize(I);

    if (displacement("dentmask", dent) == 0) {
        /* No displacement information: make a similar pattern ourselves. */
        dent = smoothstep(.6, 1, noise(transform("shader", P) * 6));
    }
    displacement("bumpheight", height);

    float grime = dirt * clamp(dent + 10 * max(0, -height), 0, 1);
    grime *= .7 + .3 * noise(P * 30);
    color C = mix(paintcolor, dirtcolor, grime);

    Oi = Os;
    Ci = Os * C * (Ka * ambient() + Kd * LocIllumOrenNayar(Nf, V, roughangle));
}
