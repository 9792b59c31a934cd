/*
 * distantlight.sl -- RenderMan Interface Specification 3.2, Appendix A
 * (standard light source shaders): "distantlight".
 *
 * A light infinitely far away, shining in one direction (from "from"
 * towards "to") with constant intensity and no falloff, like the sun.
 * The two points are given in shader space.
 *
 * Parameters:
 *   intensity  -- brightness of the light (1).
 *   lightcolor -- colour of the light (1, white).
 *   from       -- a point the light direction starts from (shader origin).
 *   to         -- a point the light shines towards (shader (0,0,1)).
 *   __category -- the categories it belongs to, comma separated ("").
 *   __nondiffuse, __nonspecular -- 1 leaves the light out of diffuse(),
 *                 and of specular() and phong() (RenderMan's convention; 0).
 */
light distantlight(float intensity = 1; color lightcolor = 1;
                   point from = point "shader" (0, 0, 0);
                   point to = point "shader" (0, 0, 1);
                   string __category = "";
                   output float __nondiffuse = 0;
                   output float __nonspecular = 0;)
{
    solar(to - from, 0.0)
        Cl = intensity * lightcolor;
}
