/*
 * skylight_solar.sl -- a uniform sky fill light shining from every
 * direction at once, scaled by the surface's diffuse coefficient (read by
 * message passing) and optionally by a texture map's average colour.
 *
 * Exercises: solar() with no arguments (light from all directions),
 * the surface("Kd", kd) message from a light shader, textureinfo()
 * before texture(), texture() with "width" 0, an ambient-like constant
 * colour, and a string parameter used in a test.
 */
light skylight_solar(
    float intensity = .4;
    color skycolor = color(.5, .6, .9);
    string skymap = "";
    output uniform float __nonspecular = 1;)
{
    float kd = 1;
    uniform float res[2] = {0, 0};
    color tint = 1;

    surface("Kd", kd);
    if (skymap != "" && textureinfo(skymap, "resolution", res) != 0)
        tint = color texture(skymap, .5, .5, "width", 0);

    solar() {
        Cl = intensity * skycolor * tint * clamp(kd, 0, 1);
    }
}
