/*
 * orange_peel_paint.sl -- glossy enamel paint with the "orange peel"
 * ripple of sprayed coats: the ripple bumps the normal in shader space
 * (so it sticks to the object), reflections come from an environment map
 * looked up in a named space with blur growing with the ripple, and a
 * metallic flake layer sparkles per cell.
 *
 * Exercises: bump mapping in a surface shader via
 * N = normalize(calculatenormal(P + amp * normalize(N))), scaling the
 * bump amplitude by the length of a shader-space normal
 * (ntransform("shader", N)) so it is independent of object scale,
 * fBm_aa() from a header with the filter width from filterwidthp(),
 * environment() with "blur" and "samples", reflect(), vtransform to a
 * named space, fresnel() with five arguments for the clearcoat weight,
 * cellnoise(point) per flake cell, and the __nonspecular-aware
 * highlight function from shade_models.h.
 */
#include "fractals.h"
#include "shade_models.h"

surface orange_peel_paint(
    float Ka = 0.5, Kd = 0.6, Ks = 0.8, Kr = 0.6, roughness = 0.02;
    color basecolor = color(0.7, 0.05, 0.05);
    float peelamp = 0.002, peelfreq = 40;
    float flakedensity = 0.3, flakefreq = 400, Kflake = 0.4;
    string envname = "", envspace = "world";
    float envblur = 0.005, envsamples = 4;
    float eta = 1.5;)
{
    point Psh = transform("shader", P);
    float fw = filterwidthp(Psh * peelfreq);

    /* Orange peel: bump measured in shader-space units. */
    float peel = fBm_aa(Psh * peelfreq, fw, 4, 2.1, 0.5);
    normal Nsh = ntransform("shader", N);
    float scaleamp = peelamp / max(length(Nsh), 1.0e-6) * length(N);
    normal Nb = normalize(calculatenormal(P + scaleamp * peel * normalize(N)));
    normal Nf = faceforward(Nb, I);
    vector V = -normalize(I);

    /* Clearcoat Fresnel weight. */
    float kr, kt;
    fresnel(normalize(I), Nf, 1 / eta, kr, kt);

    /* Environment reflection, blur growing with how rough the peel is here. */
    color refl = 0;
    if (envname != "") {
        vector R = vtransform(envspace, reflect(normalize(I), Nf));
        float b = envblur * (1 + 4 * abs(peel));
        refl = color environment(envname, R, "blur", b, "samples", envsamples);
    }

    /* Flakes: a sparse random subset of small cells catches the light. */
    point cell = Psh * flakefreq;
    float isflake = step(1 - flakedensity, float cellnoise(cell));
    vector flakedir = normalize(vector cellnoise(cell + 17) - 0.5);
    normal Nflake = normalize(Nf + 0.5 * normal vtransform("shader", "current", flakedir));
    color sparkle = isflake * specular_msg(Nflake, V, 0.05)
                  * (1 - smoothstep(0.5, 1, filterwidthp(cell)));

    Oi = Os;
    /* What the clearcoat does not reflect reaches the paint underneath. */
    Ci = Os * (kt * (basecolor * (Ka * ambient() + Kd * diffuse_msg(Nf))
                     + Kflake * basecolor * sparkle)
               + Ks * specular_msg(Nf, V, roughness)
               + Kr * kr * refl);
}
