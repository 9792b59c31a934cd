/*
 * raytrace.h -- helpers for ray-traced reflection and refraction.
 *
 * Exercises: include guards, #include "config.h", extern globals in
 * functions, gather() with an else branch and a "surface:Ci" output,
 * trace(), environment(), fresnel() with seven arguments, string
 * comparison, early return statements, #if defined() with an #else.
 */
#ifndef RAYTRACE_H
#define RAYTRACE_H

#include "config.h"

#if defined(RAYTRACE_NO_GATHER)
#define RT_USE_GATHER 0
#else
#define RT_USE_GATHER 1
#endif

/*
 * Reflection colour along R: a traced ray when envname is "raytrace", an
 * environment map lookup (in world space) when a map is named, and black
 * otherwise.
 */
color ReflectionColor(string envname; vector R; float blur)
{
    extern point P;
    if (envname == "raytrace")
        return trace(P, R);
    if (envname != "")
        return color environment(envname, vtransform("world", R), "blur", blur);
    return color 0;
}

/*
 * Blurry reflection by averaging many rays in a cone around R.  Rays that
 * leave the scene see "background".
 */
color GlossyReflection(vector R; float coneangle, samples; color background)
{
    extern point P;
    color sum = 0, hitc = 0;
    float n = 0;

#if RT_USE_GATHER
    gather("illuminance", P, R, coneangle, samples, "surface:Ci", hitc) {
        sum += hitc;
        n += 1;
    } else {
        sum += background;
        n += 1;
    }
#else
    sum = trace(P, R);
    n = 1;
#endif
    return sum / max(n, 1);
}

/* Fresnel split of the incident direction into reflected and transmitted rays. */
void FresnelRays(vector In; normal Nf; float eta;
                 output float Kr, Kt; output vector R, T)
{
    fresnel(In, Nf, eta, Kr, Kt, R, T);
}

#endif /* RAYTRACE_H */
