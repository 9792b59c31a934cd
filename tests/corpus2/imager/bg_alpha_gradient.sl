/*
 * bg_alpha_gradient.sl -- an imager that puts a vertical gradient (or
 * a flat colour, or a texture) behind the rendered image wherever its
 * coverage is incomplete, then makes the pixel fully opaque.
 *
 * Exercises: an imager shader reading alpha, Ci and the raster-space P,
 * option("Format", res) into a uniform float array of three, a
 * gradient over raster y normalised by the resolution, texture() with
 * explicit (s,t) from raster position, a spline() colour ramp through
 * literal colours, the premultiplied "over" composite
 * Ci += (1 - alpha) * bg, and writing Oi and alpha.
 */
imager bg_alpha_gradient(
    string mode = "gradient";            /* "flat", "gradient" or "texture" */
    color bgcolor = color(0.2, 0.2, 0.25);
    color topcolor = color(0.15, 0.25, 0.5), horizoncolor = color(0.8, 0.75, 0.7),
          bottomcolor = color(0.3, 0.28, 0.25);
    float horizon = 0.55;                 /* fraction of the height, from the top */
    string bgtexture = "";
    float keepalpha = 0;)
{
    uniform float res[3] = {640, 480, 1};
    if (option("Format", res) == 0) {
        res[0] = 640;
        res[1] = 480;
    }
    float x = xcomp(P) / res[0];
    float y = ycomp(P) / res[1];          /* 0 at the top */

    color bg = bgcolor;
    if (mode == "gradient") {
        float k = (y < horizon) ? 0.5 * y / horizon
                                : 0.5 + 0.5 * (y - horizon) / (1 - horizon);
        bg = spline("linear", k, topcolor, topcolor, horizoncolor, bottomcolor, bottomcolor);
    } else if (mode == "texture" && bgtexture != "") {
        bg = color texture(bgtexture, x, y);
    }

    Ci += (1 - alpha) * bg;
    Oi = 1;
    if (keepalpha == 0)
        alpha = 1;
}
