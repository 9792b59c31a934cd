/*
 * defaultsurface.sl -- the surface RenderMan renderers give objects that
 * name none (PRMan's "defaultsurface"), also asked for by name in RIB files.
 *
 * Lights are not looked at: the surface is shaded by how squarely it faces
 * the eye, Ka + Kd * cos^2 of the angle between the view direction and the
 * normal, times its colour Cs and opacity Os.
 *
 * Parameters:
 *   Ka -- the part that does not depend on the angle (.2).
 *   Kd -- the part that does (.8).
 */
surface defaultsurface(float Kd = .8; float Ka = .2;)
{
    float d = normalize(I) . normalize(N);
    Oi = Os;
    Ci = Os * Cs * (Ka + Kd * d * d);
}
