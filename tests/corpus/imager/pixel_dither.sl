/*
 * pixel_dither.sl -- quantises the image to a small number of levels per
 * channel (for simulating low bit depths), with either random dither or
 * ordered dither from a 4x4 Bayer matrix.
 *
 * Exercises: the "pixel" shader type, a local float array of 16 elements
 * with an initialiser indexed by a computed index, mod() and floor() on
 * the raster position P, random() (fresh per call), cellnoise() as a
 * repeatable per-pixel random, string switches, comp()/setcomp() in a
 * loop, and the ?: operator.
 */
pixel pixel_dither(
    float levels = 16;
    string method = "ordered";
    float amount = 1;)
{
    float bayer[16] = { 0,  8,  2, 10,
                       12,  4, 14,  6,
                        3, 11,  1,  9,
                       15,  7, 13,  5};
    float px = floor(xcomp(P)), py = floor(ycomp(P));
    float idx = mod(py, 4) * 4 + mod(px, 4);
    float threshold;

    if (method == "ordered")
        threshold = (bayer[idx] + .5) / 16;
    else if (method == "random")
        threshold = random();
    else
        threshold = float cellnoise(point(px, py, 0));

    color c = Ci;
    float i;
    for (i = 0; i < 3; i += 1) {
        float x = comp(c, i) * (levels - 1);
        float q = floor(x + mix(.5, threshold, amount));
        setcomp(c, i, clamp(q / (levels - 1), 0, 1));
    }
    Ci = (levels > 1) ? c : Ci;
}
