/*
 * category_plastic.sl -- plastic whose light loops are steered by light
 * categories and the __nondiffuse/__nonspecular messages: fill lights
 * never make highlights, lights in category "specular" only make
 * highlights, and rim lights add a separate edge term.
 *
 * Exercises: #define of a feature toggle before #include, the SPECFUNC
 * macro chosen by #ifdef, illuminance with the categories "-specular",
 * "specular" and "rim", lightsource("__nonspecular", ns) and
 * lightsource("__nondiffuse", nd) inside the loops, specularbrdf() per
 * light, a function-style macro (ACCUM_DIFFUSE) expanding to a whole
 * illuminance statement, faceforward, and the ambient() term.
 */
#define USE_FANCY_SPEC 1
#include "shade_models.h"

surface category_plastic(
    float Ka = 1, Kd = 0.5, Ks = 0.5, roughness = 0.1, sharpness = 0;
    color specularcolor = 1;
    float Krim = 0.5, rimwidth = 0.25;
    color rimcolor = 1;)
{
    normal Nf = faceforward(normalize(N), I);
    vector V = -normalize(I);

    /* Diffuse: every light that does not opt out, via the header macro. */
    color diff = 0;
    ACCUM_DIFFUSE(diff, P, Nf)

    /* Highlights from lights not in category "specular", honouring __nonspecular. */
    color spec = 0;
    illuminance("-specular", P, Nf, PI / 2) {
        float ns = 0;
        lightsource("__nonspecular", ns);
        spec += (1 - ns) * Cl * specularbrdf(normalize(L), Nf, V, roughness);
    }

    /* Lights in category "specular" are highlight-only "kickers". */
    illuminance("specular", P, Nf, PI / 2) {
        spec += Cl * specularbrdf(normalize(L), Nf, V, roughness / 2);
    }

    /* Optionally a sharp-edged glossy highlight as well (toggle from the header). */
    if (sharpness > 0)
        spec += SPECFUNC(Nf, V, roughness);

    /* Rim lights: only at grazing view angles, whatever their direction. */
    color rim = 0;
    float edge = smoothstep(1 - rimwidth, 1, 1 - abs(Nf . V));
    illuminance("rim", P) {
        rim += Cl * edge;
    }

    Oi = Os;
    Ci = Os * (Cs * (Ka * ambient() + Kd * diff)
               + Ks * specularcolor * spec
               + Krim * rimcolor * rim);
}
