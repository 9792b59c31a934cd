/*
 * vignette.sl -- rtsl's standard pixel shaders: "vignette".
 *
 * Darkens the image towards its corners, as a lens does.  The distance
 * from the image centre is measured in units of the half diagonal (0 at the
 * centre, 1 in the corners); the pixel is darkened by up to `strength`,
 * fading in smoothly between radius - softness and radius + softness.
 *
 * Parameters:
 *   strength -- how dark the corners get, 0 to 1 (.5).
 *   radius   -- where the darkening is half done (.8).
 *   softness -- half the width of the fade (.4).
 */
pixel vignette(float strength = .5; float radius = .8; float softness = .4;)
{
    uniform float format[3] = {640, 480, 1};
    option("Format", format);
    float x = 2 * xcomp(P) / format[0] - 1;
    float y = 2 * ycomp(P) / format[1] - 1;
    float r = sqrt(x * x + y * y) / sqrt(2);
    Ci *= 1 - strength * smoothstep(radius - softness, radius + softness, r);
}
