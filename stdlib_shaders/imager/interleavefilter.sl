/*
 * interleavefilter.sl -- rtsl's standard pixel shaders: "interleavefilter".
 *
 * The filter of interleaved sampling (Keller and Heidrich 2001): the light of
 * each pixel becomes the mean of the size x size pixels around it that see the
 * same object at a similar depth and with a similar normal (a discontinuity
 * buffer), so the pattern of noise that interleaved virtual lights leave
 * (Option "gi" "interleave", docs/global_illumination.md) is smoothed within
 * surfaces, never across their edges or creases.  Pixels that see nothing
 * are left as they are.
 *
 * Where the surface says which part of its colour is indirect light (the
 * output variables "indirect", the light, and "indirectweight", what Ci
 * weighs it by, as "gimatte" gives them), only that part is smoothed, as in
 * Wald et al.'s interactive global illumination: the pixel keeps its direct
 * light and its texture, and its indirect light becomes its weight times the
 * mean indirect light around it.  Elsewhere (a surface without them, a
 * weight of zero) the whole colour is smoothed.
 *
 * Parameters:
 *   size            -- the side of the block averaged: the interleaving's (3).
 *   depthtolerance  -- neighbours whose depth differs from the pixel's by more
 *                      than this fraction of it are left out (0.05).
 *   normaltolerance -- neighbours whose normal's dot product with the pixel's
 *                      is below this are left out (0.9, about 25 degrees;
 *                      -1 takes every normal).
 */
pixel interleavefilter(float size = 3; float depthtolerance = 0.05; float normaltolerance = 0.9;)
{
    float x = xcomp(P), y = ycomp(P);
    float z = zdepth, id = objectid;
    color pn = color pixelvalue("N", x, y);
    color weight = color pixelvalue("indirectweight", x, y);
    float split = comp(weight, 0) != 0 || comp(weight, 1) != 0 || comp(weight, 2) != 0 ? 1 : 0;
    float format[3];
    option("Format", format);
    if (id >= 0) {
        color sum = 0;
        float n = 0;
        float r = floor(size / 2);
        float dx, dy;
        for (dy = -r; dy <= r; dy += 1) {
            for (dx = -r; dx <= r; dx += 1) {
                float nx = x + dx, ny = y + dy;
                if (nx >= 0 && ny >= 0 && nx < format[0] && ny < format[1]) {
                    float nz = pixelvalue("z", nx, ny);
                    if (pixelvalue("objectid", nx, ny) == id && abs(nz - z) <= depthtolerance * z) {
                        color nn = color pixelvalue("N", nx, ny);
                        float facing = comp(pn, 0) * comp(nn, 0) + comp(pn, 1) * comp(nn, 1)
                            + comp(pn, 2) * comp(nn, 2);
                        if (facing >= normaltolerance) {
                            if (split != 0)
                                sum += color pixelvalue("indirect", nx, ny);
                            else
                                sum += color pixelvalue("Ci", nx, ny);
                            n += 1;
                        }
                    }
                }
            }
        }
        if (n > 0) {
            if (split != 0)
                Ci += weight * (sum / n - color pixelvalue("indirect", x, y));
            else
                Ci = sum / n;
        }
    }
}
