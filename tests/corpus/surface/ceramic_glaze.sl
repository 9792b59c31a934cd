/*
 * ceramic_glaze.sl -- glazed ceramic: a coloured clay body seen through a
 * glossy clear glaze, with pooling of the glaze in crevices, a crackle
 * pattern, and reflections from an environment map or from ray tracing.
 *
 * Exercises: #include "raytrace.h" (ReflectionColor with string compare
 * and early returns), environment() called directly with "blur",
 * illuminance("-specular", P, N, angle) for the body, reflect(), fresnel()
 * with output arguments, voronoi_f1() cells for crackle, occlusion()
 * for glaze pooling, filterstep() with a "width" argument.
 */
#include "raytrace.h"
#include "noises.h"

surface ceramic_glaze(
    float Ka = 1, Kd = .8, Ks = .7, Kr = .6;
    float roughness = .04, eta = 1.5;
    float crackfreq = 8, crackwidth = .03;
    string envname = "";
    float envblur = .01;
    color bodycolor = color(.25, .45, .55);
    color pooledcolor = color(.1, .22, .3);)
{
    normal Nn = normalize(N);
    normal Nf = faceforward(Nn, I);
    vector In = normalize(I);
    vector V = -In;
    vector R = reflect(In, Nf);
    float Kref, Ktrans;

    fresnel(In, Nf, 1 / eta, Kref, Ktrans);

    /* Glaze pools where the surface is occluded (inside creases). */
    float occ = occlusion(P, Nf, 16, "maxdist", .5);
    color Cbody = mix(bodycolor, pooledcolor, smoothstep(.2, .7, occ));

    /* Crackle: thin dark lines along Voronoi cell borders. */
    point nearest;
    point Pc = transform("object", P) * crackfreq;
    float f1 = voronoi_f1(Pc, .9, nearest);
    float border = filterstep(.55 - crackwidth, .8 * f1, "width", filterwidthp(Pc));
    Cbody *= 1 - .5 * border;

    /* Body lighting from non-specular lights. */
    color body = 0;
    illuminance("-specular", P, Nf, PI / 2) {
        body += Cl * (normalize(L) . Nf);
    }

    /* Reflection: traced, mapped, or nothing, then a blurred sky term. */
    color refl = ReflectionColor(envname, R, envblur);
    if (envname == "")
        refl = .1 * (1 + zcomp(vtransform("world", R)));
    else if (envname != "raytrace")
        refl = mix(refl, color environment(envname, vtransform("world", R), "blur", 4 * envblur), .3);

    Oi = Os;
    Ci = Os * (Ktrans * Cbody * (Ka * ambient() + Kd * body)
               + Ks * specular(Nf, V, roughness) + Kr * Kref * refl);
}
