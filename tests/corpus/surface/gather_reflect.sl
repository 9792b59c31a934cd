/*
 * gather_reflect.sl -- a glossy reflective surface whose blurry
 * reflections come from sampling a cone of rays, with the hit distance
 * used to sharpen reflections of nearby objects (contact hardening).
 *
 * Exercises: gather("illuminance", ...) written directly in the shader
 * with two output queries ("surface:Ci" and "ray:length") and an else
 * branch for rays that miss, GlossyReflection() from raytrace.h (a second
 * gather in a function), reflect(), environment() for the misses,
 * string comparison, degrees/radians, division by a running count,
 * and += on floats and colours.
 */
#include "raytrace.h"

surface gather_reflect(
    float Ka = 1, Kd = .4, Ks = .5, Kr = .8, roughness = .08;
    float blurangle = 8;
    float samples = 16;
    string envname = "";)
{
    normal Nf = faceforward(normalize(N), I);
    vector V = -normalize(I);
    vector R = normalize(reflect(I, Nf));
    uniform float cone = radians(blurangle);
    color hitc = 0, sum = 0;
    float hitdist = 0, nearest = 1e30, nhits = 0, nmiss = 0;

    gather("illuminance", P, R, cone, samples,
           "surface:Ci", hitc, "ray:length", hitdist) {
        sum += hitc;
        nearest = min(nearest, hitdist);
        nhits += 1;
    } else {
        if (envname != "")
            sum += color environment(envname, vtransform("world", R));
        nmiss += 1;
    }
    color blurry = sum / max(1, nhits + nmiss);

    /* Close objects reflect sharply: blend in a narrow-cone estimate. */
    float closeness = 1 - smoothstep(0, 1, nearest);
    color sharp = GlossyReflection(R, cone * .1, 4, blurry);
    color refl = mix(blurry, sharp, closeness);

    Oi = Os;
    Ci = Os * (Cs * (Ka * ambient() + Kd * diffuse(Nf))
               + Ks * specular(Nf, V, roughness) + Kr * refl);
    if (degrees(cone) > 45)
        Ci *= .9;
}
