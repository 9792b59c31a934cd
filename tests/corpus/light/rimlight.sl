/*
 * rimlight.sl -- a back light for silhouette ("rim") lighting: it lights
 * only surfaces seen nearly edge-on from the camera, and only shaders
 * that ask for lights of category "rim" (see surface/toon_bands.sl).
 *
 * Exercises: illuminate(from) with the __category string "rim", the
 * __nondiffuse and __nonspecular outputs, the camera position as
 * point "camera" (0,0,0), normalize(), the dot product of L with the view
 * direction, and pow() falloff.
 */
light rimlight(
    float intensity = 1;
    color lightcolor = 1;
    point from = point "shader" (0, 0, 0);
    float rimwidth = .3, rimpower = 2;
    uniform string __category = "rim";
    output uniform float __nondiffuse = 1;
    output uniform float __nonspecular = 1;)
{
    point eye = point "camera" (0, 0, 0);

    illuminate(from) {
        /* How directly the light faces the camera, seen from the surface. */
        vector toeye = normalize(eye - Ps);
        float backness = max(0, -(normalize(L) . toeye));
        float rim = pow(smoothstep(1 - rimwidth, 1, backness), rimpower);
        Cl = intensity * lightcolor * rim;
    }
}
