/*
 * thinlens.sl -- rtsl's standard camera shaders: "thinlens".
 *
 * Depth of field: rays start on a circular lens aperture (the lens sample
 * u, v, mapped to the disc by Shirley and Chiu's concentric map) and pass
 * through the point of the focal plane that the pinhole ray through their
 * pixel meets, so only that plane is sharp.  The renderer gives the whole
 * packet one lens sample, so its rays share an origin and stay coherent.
 * As in RenderMan's DepthOfField, the aperture's diameter is
 * focallength / fstop, in scene units.
 *
 * Parameters:
 *   fov -- field of view across the shorter side, degrees (0: the scene's).
 *   fstop, focallength, focaldistance -- the lens (0: the scene's RIB
 *          DepthOfField, or f/2.8, 0.05 and 5 when it has none).
 */
camera thinlens(float fov = 0; float fstop = 0; float focallength = 0; float focaldistance = 0;)
{
    uniform float f = fov;
    if (f <= 0)
        option("FieldOfView", f);
    uniform float dof[3] = {2.8, .05, 5};
    option("DepthOfField", dof);
    uniform float fs = (fstop > 0) ? fstop : dof[0];
    uniform float fl = (focallength > 0) ? focallength : dof[1];
    uniform float fd = (focaldistance > 0) ? focaldistance : dof[2];
    uniform float halfwidth = tan(radians(f) / 2);
    uniform float radius = fl / (2 * fs);

    /* The concentric map of the unit square onto the unit disc. */
    float a = 2 * u - 1, b = 2 * v - 1;
    float r = 0, phi = 0;
    if (abs(a) > abs(b)) {
        r = a;
        phi = (PI / 4) * (b / a);
    } else if (b != 0) {
        r = b;
        phi = PI / 2 - (PI / 4) * (a / b);
    }
    /* The lens point is one per packet; the direction from it to the focal
     * plane is cast as a vector, which costs less per ray than casting the
     * focal point and subtracting. */
    uniform float lx = radius * r * cos(phi), ly = radius * r * sin(phi);
    /* Screen position to the focal plane's, worked out once. */
    uniform float tofocus = halfwidth * fd;
    E = point "camera" (lx, ly, 0);
    I = vector "camera" (s * tofocus - lx, t * tofocus - ly, fd);
    Ci = 1;
}
