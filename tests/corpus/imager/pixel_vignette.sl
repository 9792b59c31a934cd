/*
 * pixel_vignette.sl -- lens vignetting applied per pixel: the image darkens
 * towards the corners with the cos^4 law of a simple lens, plus an
 * artistic smoothstep falloff.
 *
 * Exercises: the "pixel" shader type (a synonym of imager), option("Format")
 * for the image size and pixel aspect ratio, the raster position P, cos()
 * and atan(), tan(), pow(), sqrt(), and uniform locals derived from an
 * option.
 */
pixel pixel_vignette(
    float fieldofview = 60;
    float strength = 1;
    float innerradius = .6, outerradius = 1.4;)
{
    uniform float fmt[3] = {640, 480, 1};
    option("Format", fmt);
    uniform float cx = fmt[0] / 2, cy = fmt[1] / 2;
    uniform float halfdiag = sqrt(cx * cx * fmt[2] * fmt[2] + cy * cy);

    float dx = (xcomp(P) - cx) * fmt[2], dy = ycomp(P) - cy;
    float r = sqrt(dx * dx + dy * dy) / halfdiag;

    /* Natural vignetting: cos^4 of the off-axis angle. */
    float offaxis = atan(r * tan(radians(fieldofview) / 2));
    float natural = pow(cos(offaxis), 4);

    /* Artistic vignetting: a soft ring. */
    float artistic = 1 - smoothstep(innerradius, outerradius, r);

    float k = mix(1, natural * artistic, strength);
    Ci *= k;
}
