/*
 * stripes_aa.sl -- awning stripes of two widths with a thin pinstripe,
 * all box-filtered analytically, and a colour that fades to the average
 * when the stripes are too fine to resolve.
 *
 * Exercises: filteredpulsetrain() from a header (macro-built integrals
 * with floor()), filteredpulse(), filteredabs(), the filterwidth()
 * macro applied to an expression, clampedfilterwidth() built on top of
 * it, a uniform duty-cycle computed from parameters, a fade-to-average
 * with smoothstep on the filter width, a "t" or "s" direction chosen by
 * a string parameter, and a triangle wave from filteredabs.
 */
#include "aa_filters.h"

surface stripes_aa(
    float Ka = 1, Kd = 0.8;
    color colorA = color(0.8, 0.1, 0.1), colorB = color(0.95, 0.92, 0.85);
    color pincolor = color(0.1, 0.1, 0.3);
    float frequency = 12, duty = 0.5;
    float pinwidth = 0.04;
    float wave = 0.02, wavefreq = 3;
    string direction = "s";)
{
    /* Coordinate across the stripes, with a gentle sag. */
    float across = (direction == "t") ? t : s;
    float along = (direction == "t") ? s : t;
    float x = across * frequency + wave * frequency * (filteredabs(mod(along * wavefreq, 1) - 0.5, 0.01) - 0.25);

    float fw = clampedfilterwidth(x, 1);
    uniform float edge = clamp(1 - duty, 0.01, 0.99);

    /* Main stripes: colorB on [0, edge), colorA on [edge, 1) of each period. */
    float main = filteredpulsetrain(edge, 1, x, fw);

    /* Pinstripe centred in colorB. */
    float xf = x - floor(x);
    float pin = filteredpulse(edge / 2 - pinwidth / 2, edge / 2 + pinwidth / 2, xf, fw);

    color Ct = mix(colorB, colorA, main);
    Ct = mix(Ct, pincolor, pin);

    /* Where a single sample spans several stripes, blend to the mean. */
    color avg = mix(colorB, colorA, duty) * (1 - pinwidth) + pincolor * pinwidth;
    Ct = mix(Ct, avg, smoothstep(0.5, 1, fw));

    normal Nf = faceforward(normalize(N), I);
    Oi = Os;
    Ci = Os * Ct * (Ka * ambient() + Kd * diffuse(Nf));
}
