/*
 * background_gradient.sl -- composites the image over a vertical gradient
 * (sky-like, from a top colour down to a bottom colour) instead of a
 * constant colour.
 *
 * Exercises: an imager shader reading the raster position P, alpha, Ci
 * and Oi and writing all three, option("Format") into a uniform float
 * array with a fallback when the option is missing, a color spline() with
 * the "linear" basis, smoothstep(), and the premultiplied "over"
 * composite.
 */
imager background_gradient(
    color topcolor = color(.2, .35, .7);
    color horizoncolor = color(.8, .85, .9);
    color bottomcolor = color(.3, .3, .3);
    float horizon = .55;
    float softness = .1;)
{
    uniform float fmt[3] = {640, 480, 1};
    if (option("Format", fmt) == 0)
        fmt[1] = 480;

    /* 0 at the top row of the image, 1 at the bottom. */
    float y = clamp(ycomp(P) / fmt[1], 0, 1);
    float below = smoothstep(horizon - softness, horizon + softness, y);
    color sky = color spline("linear", y / max(horizon, .01),
                             topcolor, topcolor, horizoncolor, horizoncolor);
    color bg = mix(sky, bottomcolor, below);

    Ci += (1 - alpha) * bg;
    Oi = 1;
    alpha = 1;
}
