/*
 * orthographic.sl -- rtsl's standard camera shaders: "orthographic".
 *
 * RenderMan's orthographic projection (RIB Projection "orthographic"):
 * parallel rays along the camera's +z, one from each point of the screen
 * window on the camera's z = 0 plane, so that a camera-space (x, y) lands
 * on screen position (x, y) and sizes do not shrink with distance.  The
 * window (RIB ScreenWindow) is in camera-space units: by default the
 * shorter side of the image spans [-1, 1].
 *
 * Parameters:
 *   scale -- widens the window by this factor (1).
 */
camera orthographic(float scale = 1;)
{
    E = point "camera" (s * scale, t * scale, 0);
    I = vector "camera" (0, 0, 1);
    Ci = 1;
}
