/*
 * gamma_clamp_dither.sl -- output conditioning: exposure in stops,
 * a soft shoulder instead of a hard clip, per-channel gamma, optional
 * conversion through a colour space, and ordered-plus-random dithering
 * before quantising to a given number of levels.
 *
 * Exercises: pow() on a colour with a float exponent and with a colour
 * exponent, clamp() on colours against colour bounds, ctransform()
 * to and from "hsv", comp()/setcomp() on Ci, a 4x4 Bayer matrix as a
 * float array indexed by mod() of the raster position, random(),
 * floor() quantisation, alpha unpremultiply and repremultiply with a
 * guard, a macro with a ?: for safe division, and the imager globals
 * Ci, Oi, alpha and P.
 */
#define SAFEDIV(a, b) (((b) != 0) ? (a) / (b) : (a))

imager gamma_clamp_dither(
    float exposure = 0;                  /* stops */
    float gamma = 2.2;
    color channelgamma = 1;
    float shoulder = 0.8;                /* where the soft clip starts */
    float saturation = 1;
    float one = 255;                     /* quantisation levels - 1 */
    float dither = 1;
    float randomdither = 0.5;)
{
    float bayer[16] = {0, 8, 2, 10, 12, 4, 14, 6, 3, 11, 1, 9, 15, 7, 13, 5};

    /* Work on unpremultiplied colour. */
    color c = SAFEDIV(Ci, alpha);
    c *= pow(2, exposure);

    /* Soft shoulder: linear below `shoulder`, asymptotic to 1 above. */
    uniform float i;
    for (i = 0; i < 3; i += 1) {
        float x = comp(c, i);
        if (x > shoulder) {
            float over = (x - shoulder) / (1 - shoulder);
            x = shoulder + (1 - shoulder) * over / (1 + over);
        }
        setcomp(c, i, x);
    }

    /* Saturation through HSV. */
    if (saturation != 1) {
        color hsv = ctransform("hsv", c);
        setcomp(hsv, 1, clamp(comp(hsv, 1) * saturation, 0, 1));
        c = ctransform("hsv", "rgb", hsv);
    }

    c = clamp(c, color 0, color 1);
    c = pow(c, 1 / gamma);
    c = pow(c, 1 / channelgamma);

    /* Dither: ordered threshold plus a little noise, then quantise. */
    float bx = mod(floor(xcomp(P)), 4), by = mod(floor(ycomp(P)), 4);
    float threshold = (bayer[bx + 4 * by] + 0.5) / 16;
    float noiseval = randomdither * (float random() - 0.5);
    color q = floor(c * one + dither * (threshold + noiseval)) / one;

    Ci = clamp(q, color 0, color 1) * alpha;
    Oi = alpha;
}
