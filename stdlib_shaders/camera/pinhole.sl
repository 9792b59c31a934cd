/*
 * pinhole.sl -- rtsl's standard camera shaders: "pinhole".
 *
 * The ideal perspective camera: every ray starts at the camera's origin and
 * passes through its point of the screen window.  With fov = 0 it takes the
 * scene's field of view (RIB Projection "perspective" "fov"), so it makes
 * exactly the rays of the built-in camera; it is the reference the other
 * camera shaders are measured against.
 *
 * Parameters:
 *   fov -- field of view across the image's shorter side, in degrees
 *          (0: the scene's).
 *   screenoffset -- shifts the screen window (a lens shift), in units of
 *          half the shorter side.
 */
camera pinhole(float fov = 0; float screenoffsetx = 0; float screenoffsety = 0;)
{
    uniform float f = fov;
    if (f <= 0)
        option("FieldOfView", f);
    uniform float halfwidth = tan(radians(f) / 2);
    E = point "camera" (0, 0, 0);
    I = vector "camera" ((s + screenoffsetx) * halfwidth, (t + screenoffsety) * halfwidth, 1);
    Ci = 1;
}
