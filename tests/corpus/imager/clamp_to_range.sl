/*
 * clamp_to_range.sl -- keeps pixel values within a displayable range,
 * either by hard clipping each channel or by a soft shoulder that rolls
 * highlights off smoothly, and optionally flags out-of-range pixels in a
 * warning colour.
 *
 * Exercises: an imager shader, comp() and setcomp() on colours in a
 * for loop over the three channels, min()/max()/clamp(), a user function
 * with an early return, string comparison of a mode parameter, the
 * rendererinfo("renderer") call, and the || operator.
 */
float softclip(float x, shoulder, maxval)
{
    if (x <= shoulder)
        return x;
    float range = maxval - shoulder;
    return shoulder + range * (1 - exp(-(x - shoulder) / range));
}

imager clamp_to_range(
    float minvalue = 0, maxvalue = 1;
    float shoulder = .8;
    string mode = "soft";
    float showclipped = 0;
    color warncolor = color(1, 0, 1);)
{
    color c = Ci;
    float i, clipped = 0;
    uniform string renderer = "";

    rendererinfo("renderer", renderer);

    for (i = 0; i < 3; i += 1) {
        float x = comp(c, i);
        if (x < minvalue || x > maxvalue)
            clipped = 1;
        if (mode == "soft")
            x = softclip(max(x, minvalue), shoulder * maxvalue, maxvalue);
        setcomp(c, i, clamp(x, minvalue, maxvalue));
    }

    if (showclipped > 0 && clipped > 0 && renderer != "")
        c = warncolor;

    Ci = c;
    alpha = clamp(alpha, 0, 1);
}
