/*
 * glass_trace.sl -- thin or solid glass: Fresnel split into reflected and
 * refracted rays, each traced while the ray depth allows and otherwise
 * looked up in an environment map (or left black), with Beer's-law tint
 * for a given thickness and a cheap highlight.
 *
 * Exercises: fresnel(I, N, eta, Kr, Kt, R, T) with all seven arguments,
 * eta inverted when leaving the object (In . Nn test), trace() with
 * "samples"/"samplecone"/"bias" options, raydepth() in a uniform local
 * limiting recursion, environment() with "blur" as fallback,
 * vtransform(string, v) with a string parameter for the space, fewer
 * samples on secondary rays, exp() of a colour, refract() checked for
 * total internal reflection, and specular().
 */
#ifndef GLASS_MAXDEPTH
#define GLASS_MAXDEPTH 6
#endif

/* Look a direction up: trace if allowed, else the environment, else black. */
color glass_lookup(point Pt; vector dir; uniform float allowtrace;
                   string envname, envspace; float envblur, samples, cone)
{
    color C = 0;
    if (allowtrace != 0) {
        C = trace(Pt, dir, "samples", samples, "samplecone", cone, "bias", 0.001);
    } else if (envname != "") {
        vector Denv = normalize(vtransform(envspace, dir));
        C = color environment(envname, Denv, "blur", envblur);
    }
    return C;
}

surface glass_trace(
    float Ka = 0, Ks = 0.6, roughness = 0.05;
    float Kr = 1, Kt = 1, eta = 1.5;
    color transmitcolor = 1;
    color absorption = color(0.3, 0.05, 0.1);
    float thickness = 0.5;
    float thin = 0;                       /* 1: a pane, no bending */
    string envname = "", envspace = "world";
    float envblur = 0.01;
    uniform float maxdepth = 4;
    float samples = 4, glossangle = 0;)
{
    normal Nn = normalize(N);
    vector In = normalize(I);
    float entering = (In . Nn < 0) ? 1 : 0;
    normal Nf = (entering != 0) ? Nn : -Nn;
    float ior = (entering != 0) ? 1 / eta : eta;

    float kr, kt;
    vector R, T;
    fresnel(In, Nf, ior, kr, kt, R, T);

    /* Total internal reflection: refract() gives the zero vector. */
    vector Tcheck = refract(In, Nf, ior);
    if (Tcheck . Tcheck < 1.0e-8) {
        kr = 1;
        kt = 0;
    }
    if (thin != 0)
        T = In;                            /* a pane shifts but does not bend */

    uniform float depth = raydepth();
    uniform float cap = min(maxdepth, GLASS_MAXDEPTH);
    uniform float allow = (depth < cap) ? 1 : 0;
    uniform float nsamp = (depth == 0) ? samples : 1;
    float cone = radians(glossangle);

    color refl = 0, refr = 0;
    if (kr * Kr > 0.001)
        refl = glass_lookup(P, normalize(R), allow, envname, envspace, envblur, nsamp, cone);
    if (kt * Kt > 0.001)
        refr = glass_lookup(P, normalize(T), allow, envname, envspace, envblur, nsamp, cone);

    /* Absorption along the path inside, only when the ray leaves the glass. */
    color beer = (entering != 0) ? color 1 : exp(-absorption * thickness);

    Oi = 1;
    Ci = Ka * ambient() * transmitcolor
       + Kr * kr * refl
       + Kt * kt * transmitcolor * beer * refr
       + Ks * specular(Nf, -In, roughness);
}
