/*
 * shadow_catcher.sl -- a "shadow matte" for compositing: the surface is
 * transparent where it is lit and opaque where lights are blocked.  It
 * measures shadowing two ways: from the lights' __unshadowed_Cl output
 * (see light/uberlight_full.sl) and from their __shadowfraction report.
 *
 * Exercises: a header function with an output colour argument,
 * lightsource() on float and colour light outputs and its return value
 * used as a test, illuminance with a category taken from a string
 * parameter, counting lights inside illuminance, the LUMA() macro from a
 * header, Oi set from a float, and a matte that still shows optional
 * diffuse lighting.
 */
#include "shade_models.h"

surface shadow_catcher(
    float shadowopacity = 1;
    color shadowtint = 0;
    float keepdiffuse = 0;
    float Kd = 1;
    string onlycategory = "";
    float verbose = 0;)
{
    normal Nf = faceforward(normalize(N), I);

    /* First method: compare lit to unshadowed light. */
    color unshadowed = 0;
    color lit = diffuse_shadowsplit(Nf, unshadowed);
    float ratio = 1 - LUMA(lit) / max(LUMA(unshadowed), 1.0e-4);

    /* Second method: average what lights say about themselves. */
    float fracsum = 0, nreporting = 0, nlights = 0;
    if (onlycategory != "") {
        illuminance(onlycategory, P, Nf, PI / 2) {
            float f = 0;
            nlights += 1;
            if (lightsource("__shadowfraction", f) != 0) {
                fracsum += f;
                nreporting += 1;
            }
        }
    } else {
        illuminance(P, Nf, PI / 2) {
            float f = 0;
            nlights += 1;
            if (lightsource("__shadowfraction", f) != 0) {
                fracsum += f;
                nreporting += 1;
            }
        }
    }
    float reported = (nreporting > 0) ? fracsum / nreporting : 0;

    float shadowed = clamp(max(ratio, reported), 0, 1) * shadowopacity;
    if (verbose > 0 && nlights == 0)
        printf("shadow_catcher: no lights in category \"%s\"\n", onlycategory);

    Oi = shadowed;
    Ci = Oi * shadowtint + keepdiffuse * Kd * Cs * lit;
}
