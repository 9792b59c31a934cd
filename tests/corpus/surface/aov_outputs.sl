/*
 * aov_outputs.sl -- plastic that writes its lighting components to
 * separate output variables (arbitrary output variables) for compositing,
 * and darkens crevices using the height that the displacement shader
 * reports.
 *
 * Exercises: output varying float / color shader parameters, an output
 * uniform parameter, a user function with several output parameters
 * (void f(float x; output float y)), the displacement("bumpheight", h)
 * and atmosphere("density", d) message-passing calls, specular(),
 * diffuse(), ambient() kept apart, and varying locals.
 */
#include "config.h"

/* Split a colour into its luminance and its chroma (colour minus grey). */
void SplitLuma(color c; output float luma; output color chroma)
{
    luma = LUMINANCE(c);
    chroma = c - color(luma);
}

/* Lighting split into its three components. */
void ShadeComponents(normal Nf; vector V; float roughness;
                     output color amb, diff, spec)
{
    amb = ambient();
    diff = diffuse(Nf);
    spec = specular(Nf, V, roughness);
}

surface aov_outputs(
    float Ka = 1, Kd = .6, Ks = .5, roughness = .1;
    float creasedarken = .5, chromaboost = 0;
    output varying color aov_diffuse = 0;
    output varying color aov_specular = 0;
    output varying float aov_luma = 0;
    output varying float aov_height = 0;
    output uniform float aov_version = 2;)
{
    normal Nf = faceforward(normalize(N), I);
    vector V = -normalize(I);
    color amb, diff, spec, chroma;
    float height = 0, fogdensity = 0;

    /* The displacement shader publishes its height as "bumpheight". */
    if (displacement("bumpheight", height) == 0)
        height = 0;
    atmosphere("density", fogdensity);

    float crease = 1 - creasedarken * smoothstep(0, -.05, height);
    ShadeComponents(Nf, V, roughness, amb, diff, spec);

    aov_diffuse = Cs * crease * (Ka * amb + Kd * diff);
    aov_specular = Ks * spec * (1 - .5 * clamp(fogdensity, 0, 1));
    aov_height = height;

    Oi = Os;
    Ci = Os * (aov_diffuse + aov_specular);
    SplitLuma(Ci, aov_luma, chroma);
    Ci += chromaboost * chroma;
    aov_version = 3;
}
