/*
 * parabolic.sl -- rtsl's standard camera shaders: "parabolic".
 *
 * The view in a parabolic mirror seen from far above, as an omnidirectional
 * camera makes: the mirror is the paraboloid z = (1 - x^2 - y^2) / 2 with
 * its focus at the camera, and the ray from the focus through the mirror
 * point under each image position is the ray traced.  The circle of
 * radius 1/scale looks sideways (90 degrees off the axis), and further out
 * the camera sees behind itself, up to the circle of radius `radius` on the
 * screen, beyond which it makes no ray.  Straight lines curve strongly: an
 * odd mapping that only a programmable camera makes easy.
 *
 * Parameters:
 *   scale -- mirror units per screen unit (1).
 *   radius -- the image circle, in screen units (1).
 */
camera parabolic(float scale = 1; float radius = 1;)
{
    float x = s * scale, y = t * scale;
    float r2 = x * x + y * y;
    E = point "camera" (0, 0, 0);
    I = vector "camera" (x, y, (1 - r2) / 2);
    Ci = (s * s + t * t <= radius * radius) ? 1 : 0;
}
