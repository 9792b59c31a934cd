/*
 * parquet_floor.sl -- a floor of staggered wooden planks: each plank has
 * its own random wood colour, grain offset and slight tilt, the gaps
 * between planks are dark, and the whole floor is varnished.
 *
 * Exercises: whichtile()/repeat() and filteredpulsetrain() from
 * patterns.h, a wood pattern written as a function nested in the shader
 * body that reaches shader parameters and locals with extern, cellnoise
 * per plank (float and vector), turbulence from noises.h, the
 * MaterialClearcoat and MaterialPlastic models from material.h, the
 * token-pasted LAYERPARAM names, and a uniform loop that precomputes
 * per-plank colour choices into a local colour array.
 */
#include "patterns.h"
#include "noises.h"
#include "material.h"

surface parquet_floor(
    float Ka = 1, Kd = .8, Ks = .3, roughness = .15;
    float LAYERPARAM(Ks, varnish) = .6;
    float varnisheta = 1.5;
    float plankwidth = .1, planklength = .8, gapwidth = .003;
    float ringfreq = 12, grainnoise = .4;
    color woodlight = color(.75, .5, .3);
    color wooddark = color(.45, .27, .13);
    color gapcolor = color(.08, .05, .03);)
{
    color woodtones[4];
    uniform float k;

    /* Four tones between light and dark wood, chosen per plank later. */
    for (k = 0; k < 4; k += 1)
        woodtones[k] = mix(woodlight, wooddark, k / 3);

    /* Plank coordinates: columns along s, staggered rows along t. */
    float col = whichtile(s, 1 / plankwidth);
    float stagger = float cellnoise(point(col, 0, 0));
    float row = whichtile(t + stagger * planklength, 1 / planklength);
    float ps = repeat(s, 1 / plankwidth);
    float pt = repeat(t + stagger * planklength, 1 / planklength);
    point plankid = point(col, row, 0);

    /* Gaps between planks, antialiased. */
    float sw = filterwidth(s / plankwidth), tw = filterwidth(t / planklength);
    float inplank = filteredpulsetrain(1 - gapwidth / plankwidth, 1,
                                       s / plankwidth, sw)
                    * filteredpulsetrain(1 - gapwidth / planklength, 1,
                                         (t + stagger * planklength) / planklength, tw);

    /* The wood of one plank, as if cut from a log at a random offset. */
    float plankwood(float ps, pt)
    {
        extern point plankid;
        extern uniform float ringfreq, grainnoise, plankwidth, planklength;
        vector offset = 10 * (vector cellnoise(plankid) - .5);
        point Pl = point(ps * plankwidth, pt * planklength, 0) + offset;
        float r = ringfreq * sqrt(SQR(xcomp(Pl)) + SQR(zcomp(Pl)) + 1);
        r += grainnoise * turbulence(Pl * 4, 3, 2, .5);
        return smoothstep(.2, .8, mod(r, 1));
    }

    float ring = plankwood(ps, pt);
    float tone = floor(4 * float cellnoise(plankid + 5));
    color Cwood = mix(woodtones[tone], wooddark, .5 * ring);
    color Cfloor = mix(gapcolor, Cwood, inplank);

    /* Planks are laid slightly unevenly: tilt each plank's normal. */
    vector tilt = .03 * (vector cellnoise(plankid + 11) - .5);
    normal Nf = faceforward(normalize(normalize(N) + tilt), I);

    color base = MaterialPlastic(Nf, Cfloor, Ka, Kd, Ks * inplank, roughness);
    Oi = Os;
    Ci = Os * (base + Ks_varnish * inplank
                      * MaterialClearcoat(Nf, color(0, 0, 0), varnisheta, .02));
}
