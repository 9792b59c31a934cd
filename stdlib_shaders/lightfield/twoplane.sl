/*
 * twoplane.sl -- rtsl's standard lightfield shaders: "twoplane".
 *
 * A two-plane light field (Levoy and Hanrahan's light slab) shown on a
 * rectangle.  The rectangle is the uv plane: x and y from -1 to 1 in its
 * object space, z = 0.  The st plane, where the light field's cameras
 * stood, is parallel to it at z = -distance.  A ray that meets the
 * rectangle at P, going along I, crossed the st plane at some (s, t): the
 * radiance it carries is looked up in the four camera images around (s, t),
 * each bilinearly at (u, v): quadrilinear interpolation.
 *
 * The light field is an ordinary image, an atlas of nviews x nviews views
 * of viewsize x viewsize pixels each, view (i, j) (i along s, j along t,
 * row 0 at the top, t = +1) at column i and row j.  `rtsl lightfield
 * capture` writes one of any scene, with the parameters to use; alpha is
 * the captured coverage, so the scene behind the rectangle shows through
 * where the light field saw nothing.  Rays that arrive from behind, or
 * that crossed the st plane outside the cameras' square, see nothing.
 *
 * Parameters:
 *   lightfield -- the atlas image.
 *   nviews -- cameras along each side of the st square (8).
 *   viewsize -- pixels along each side of one view (32).
 *   distance -- from the uv plane to the st plane, in object units (2).
 *   intensity -- scales the radiance (1).
 */
lightfield twoplane(string lightfield = ""; float nviews = 8; float viewsize = 32;
                    float distance = 2; float intensity = 1;)
{
    point Po = transform("object", P);
    vector Io = vtransform("object", I);
    Ci = 0;
    Oi = 0;
    if (lightfield != "" && zcomp(Io) > 0) {
        /* Back along the ray to the st plane. */
        float k = (zcomp(Po) + distance) / zcomp(Io);
        float ls = xcomp(Po) - k * xcomp(Io), lt = ycomp(Po) - k * ycomp(Io);
        float lu = clamp(xcomp(Po), -1, 1), lv = clamp(ycomp(Po), -1, 1);
        if (abs(ls) <= 1 && abs(lt) <= 1) {
            uniform float n = max(nviews, 2), size = max(viewsize, 1);
            /* Camera grid coordinates, and the image position within a view (texel centres
               kept half a texel inside, so bilinear filtering never reads the next view). */
            float fi = (ls + 1) / 2 * (n - 1), fj = (1 - lt) / 2 * (n - 1);
            float i0 = clamp(floor(fi), 0, n - 2), j0 = clamp(floor(fj), 0, n - 2);
            float ws = fi - i0, wt = fj - j0;
            float x = clamp((lu + 1) / 2 * size, .5, size - .5);
            float y = clamp((1 - lv) / 2 * size, .5, size - .5);
            color C = 0;
            float A = 0;
            float di, dj;
            for (dj = 0; dj <= 1; dj += 1) {
                for (di = 0; di <= 1; di += 1) {
                    float w = (di == 0 ? 1 - ws : ws) * (dj == 0 ? 1 - wt : wt);
                    float ss = ((i0 + di) * size + x) / (n * size);
                    float tt = ((j0 + dj) * size + y) / (n * size);
                    C += w * color texture(lightfield, ss, tt, "width", 0);
                    A += w * float texture(lightfield[3], ss, tt, "width", 0, "fill", 1);
                }
            }
            Ci = intensity * C;
            Oi = A;
        }
    }
}
