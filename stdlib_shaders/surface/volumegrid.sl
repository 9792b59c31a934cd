/*
 * volumegrid.sl -- a volume data set rendered by a surface shader on a
 * box, as in the OpenRT shading paper; this library's own.
 *
 * Put it on a closed box whose faces lie on boxmin..boxmax in "shader"
 * space.  Where a ray enters the box (its exit along I lies ahead of P)
 * the shader marches from P to the exit in steps of stepsize, looks the
 * grid up with texture3d() (trilinear, in shader space: the grid file's
 * own bounds should match the box) and composites front to back
 * (emission-absorption): at each step the value d is turned into a colour
 * by a ramp through four colours (spline()) and into an extinction
 * density * smoothstep(threshold, 1, d); the step absorbs
 * a = 1 - exp(-extinction * step) and adds T * a * colour.  Ci is the
 * premultiplied colour and Oi = 1 - T, so the renderer's transparency
 * continuation shows the scene behind through what is left.  Where a ray
 * leaves the box (the far faces) the shader is fully transparent.  With
 * Attribute "shade" "transmissionhitmode" "shader", shadow rays see the
 * same Oi: the volume casts a transparent shadow.
 *
 * Parameters:
 *   gridname   -- the RTSLGRID file (docs/volumes.md) ("").
 *   boxmin     -- the box's lower corner in shader space (-1, -1, -1).
 *   boxmax     -- the box's upper corner in shader space (1, 1, 1).
 *   stepsize   -- marching step in shader-space units (0.04).
 *   density    -- extinction per unit length where the value is 1 (6).
 *   threshold  -- values below this are empty (0.1).
 *   brightness -- scale on the emitted colour (1).
 *   color0..color3 -- the colour ramp from low to high values
 *                 (dark blue, teal, orange, white).
 */
surface volumegrid(string gridname = "";
                   point boxmin = point(-1, -1, -1);
                   point boxmax = point(1, 1, 1);
                   float stepsize = 0.04;
                   float density = 6;
                   float threshold = 0.1;
                   float brightness = 1;
                   color color0 = color(0.05, 0.1, 0.4);
                   color color1 = color(0.1, 0.6, 0.6);
                   color color2 = color(1, 0.55, 0.1);
                   color color3 = color(1, 1, 1);)
{
    point Ps = transform("shader", P);
    vector Ds = normalize(vtransform("shader", I));
    /* Where the ray leaves the box: the nearest far slab along each axis. */
    float tx = 1e30, ty = 1e30, tz = 1e30;
    if (xcomp(Ds) > 1e-8) tx = (xcomp(boxmax) - xcomp(Ps)) / xcomp(Ds);
    if (xcomp(Ds) < -1e-8) tx = (xcomp(boxmin) - xcomp(Ps)) / xcomp(Ds);
    if (ycomp(Ds) > 1e-8) ty = (ycomp(boxmax) - ycomp(Ps)) / ycomp(Ds);
    if (ycomp(Ds) < -1e-8) ty = (ycomp(boxmin) - ycomp(Ps)) / ycomp(Ds);
    if (zcomp(Ds) > 1e-8) tz = (zcomp(boxmax) - zcomp(Ps)) / zcomp(Ds);
    if (zcomp(Ds) < -1e-8) tz = (zcomp(boxmin) - zcomp(Ps)) / zcomp(Ds);
    float texit = min(tx, ty, tz);

    color C = 0;
    float T = 1;
    float dist = 0.5 * stepsize;
    while (dist < texit && T > 0.004) {
        float d = texture3d(gridname, Ps + dist * Ds);
        /* Below the threshold a step absorbs and adds nothing: skip its work. */
        if (d > threshold) {
            float ext = density * smoothstep(threshold, 1, d);
            float a = 1 - exp(-ext * stepsize);
            color c = brightness * spline(d, color0, color0, color1, color2, color3, color3);
            C += T * a * c;
            T *= 1 - a;
        }
        dist += stepsize;
    }
    Ci = C;
    Oi = 1 - T;
}
