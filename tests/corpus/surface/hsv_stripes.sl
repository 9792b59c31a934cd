/*
 * hsv_stripes.sl -- candy stripes whose hue rotates along s, whose
 * saturation is adjusted in HSV space, and whose lightness is adjusted in
 * HSL space, with a colour-temperature tint applied in YIQ.
 *
 * Exercises: #include by a relative path, color "hsv" (h, s, v) and color "hsl" (...) space casts,
 * ctransform("hsv", c) from the current space, ctransform("hsv", "rgb", c)
 * between two named spaces, ctransform to "YIQ" and back, comp() and
 * setcomp() on colours, a color "rgb" cast, mod(), floor(), sin(),
 * smoothstep(), and plastic lighting.
 */
#include "../include/config.h"

surface hsv_stripes(
    float Ka = 1, Kd = .7, Ks = .5, roughness = .1;
    float stripes = 12, huespan = 1, saturation = 1.2, lightness = 0;
    float warmth = .1;)
{
    float which = floor(s * stripes);
    float across = mod(s * stripes, 1);
    float edge = smoothstep(.0, .05, across) * (1 - smoothstep(.95, 1, across));

    /* Pick a hue per stripe, then push its saturation in HSV. */
    color Cstripe = color "hsv" (mod(which / stripes * huespan, 1), .6, .9);
    color hsv = ctransform("hsv", Cstripe);
    setcomp(hsv, 1, clamp(comp(hsv, 1) * saturation, 0, 1));
    Cstripe = ctransform("hsv", "rgb", hsv);

    /* Adjust lightness in HSL space. */
    color hsl = ctransform("hsl", Cstripe);
    color Clight = color "hsl" (comp(hsl, 0), comp(hsl, 1),
                             clamp(comp(hsl, 2) + lightness, 0, 1));

    /* Warm it up: shift the I (orange-blue) axis of YIQ. */
    color yiq = ctransform("YIQ", Clight);
    setcomp(yiq, 1, comp(yiq, 1) + warmth * (.5 + .5 * sin(TWOPI * t)));
    color Cfinal = ctransform("YIQ", "rgb", yiq);

    Cfinal = mix(color "rgb" (1, 1, 1), Cfinal, edge);

    normal Nf = faceforward(normalize(N), I);
    vector V = -normalize(I);
    Oi = Os;
    Ci = Os * (Cfinal * (Ka * ambient() + Kd * diffuse(Nf))
               + Ks * specular(Nf, V, roughness));
}
