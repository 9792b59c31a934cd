/*
 * thinlens_dof.sl -- a thin-lens camera with depth of field: rays start at
 * a point on the lens aperture (chosen by the lens sample u, v) and pass
 * through the point of the focal plane seen by the pinhole ray, so only
 * that plane is sharp.  A simple camera shake moves the camera with time.
 *
 * Exercises: the "camera" shader type with the lens sample (u, v) and
 * time globals, concentric square-to-disc mapping with if/else branches
 * and ?:, sin()/cos() and atan2-style atan(y, x), the "camera" space
 * casts, normalize(), vector arithmetic, and the Ci weight (aperture
 * blades modelled as a polygonal weight).
 */
#include "config.h"

camera thinlens_dof(
    float fov = 45;
    float fstop = 2.8, focallength = .05, focaldistance = 5;
    float blades = 0;
    float shake = 0, shakefreq = 3;)
{
    uniform float halfwidth = tan(radians(fov) / 2);
    uniform float aperture = focallength / (2 * fstop);

    /* Map the lens sample from the unit square onto the unit disc. */
    float a = 2 * u - 1, b = 2 * v - 1;
    float r, phi;
    if (a == 0 && b == 0) {
        r = 0;
        phi = 0;
    } else if (abs(a) > abs(b)) {
        r = a;
        phi = (PI / 4) * (b / a);
    } else {
        r = b;
        phi = (PI / 2) - (PI / 4) * (a / b);
    }
    float lx = aperture * r * cos(phi), ly = aperture * r * sin(phi);

    /* Polygonal aperture: fade the weight outside the inscribed polygon. */
    float weight = 1;
    if (blades >= 3) {
        float ang = atan(ly, lx);
        float sector = TWOPI / blades;
        float local = mod(ang, sector) - sector / 2;
        float edge = cos(sector / 2) / cos(local);
        weight = (abs(r) <= edge) ? 1 : 0;
    }

    /* Camera shake: a small sinusoidal wobble over the shutter interval. */
    vector wobble = vector "camera" (shake * sin(TWOPI * shakefreq * time),
                                     shake * cos(TWOPI * shakefreq * time * 1.3), 0);

    point focus = point "camera" (s * halfwidth * focaldistance,
                                  t * halfwidth * focaldistance, focaldistance);
    E = point "camera" (lx, ly, 0) + wobble;
    I = normalize(focus - E);
    Ci = weight;
}
