/*
 * pinhole.sl -- the ideal pinhole perspective camera: every ray starts at
 * the camera origin and passes through its point on the screen window.
 *
 * Exercises: the "camera" shader type (an rtsl extension) reading the
 * screen position s, t and writing the ray origin E, direction I and
 * weight Ci; point "camera" and vector "camera" space casts; tan() and
 * radians() of a uniform parameter; uniform locals.
 */
camera pinhole(
    float fov = 90;
    float screenoffsetx = 0, screenoffsety = 0;)
{
    uniform float halfwidth = tan(radians(fov) / 2);

    E = point "camera" (0, 0, 0);
    I = vector "camera" ((s + screenoffsetx) * halfwidth,
                         (t + screenoffsety) * halfwidth, 1);
    Ci = 1;
}
