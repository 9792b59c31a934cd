/*
 * pointlight.sl -- RenderMan Interface Specification 3.2, Appendix A
 * (standard light source shaders): "pointlight".
 *
 * An isotropic point light at "from" (given in shader space), radiating
 * equally in all directions, with physically correct inverse-square
 * falloff: the intensity is divided by the squared distance L.L.
 *
 * Parameters:
 *   intensity  -- brightness of the light (1).
 *   lightcolor -- colour of the light (1, white).
 *   from       -- position of the light (shader origin).
 *   __nondiffuse, __nonspecular -- 1 leaves the light out of diffuse(),
 *                 and of specular() and phong() (RenderMan's convention; 0).
 */
light pointlight(float intensity = 1; color lightcolor = 1;
                 point from = point "shader" (0, 0, 0);
                 output float __nondiffuse = 0;
                 output float __nonspecular = 0;)
{
    illuminate(from)
        Cl = intensity * lightcolor / (L . L);
}
