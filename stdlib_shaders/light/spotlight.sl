/*
 * spotlight.sl -- RenderMan Interface Specification 3.2, Appendix A
 * (standard light source shaders): "spotlight".
 *
 * A point light at "from" aimed at "to" that lights only a cone of
 * half-angle coneangle.  Within the cone the intensity falls off as
 * cos(angle)^beamdistribution and with the inverse square of the distance;
 * across the last conedeltaangle radians of the cone the edge is blended
 * to zero with a smoothstep.
 *
 * Parameters:
 *   intensity        -- brightness of the light (1).
 *   lightcolor       -- colour of the light (1, white).
 *   from             -- position of the light (shader origin).
 *   to               -- point the light is aimed at (shader (0,0,1)).
 *   coneangle        -- half-angle of the cone in radians (radians(30)).
 *   conedeltaangle   -- width of the soft edge in radians (radians(5)).
 *   beamdistribution -- exponent of the cosine falloff in the beam (2).
 *   __nondiffuse, __nonspecular -- 1 leaves the light out of diffuse(),
 *                 and of specular() and phong() (RenderMan's convention; 0).
 */
light spotlight(float intensity = 1; color lightcolor = 1;
                point from = point "shader" (0, 0, 0);
                point to = point "shader" (0, 0, 1);
                float coneangle = radians(30);
                float conedeltaangle = radians(5);
                float beamdistribution = 2;
                output float __nondiffuse = 0;
                output float __nonspecular = 0;)
{
    uniform vector A = (to - from) / length(to - from);
    uniform float cosoutside = cos(coneangle);
    uniform float cosinside = cos(coneangle - conedeltaangle);
    float atten, cosangle;

    illuminate(from, A, coneangle) {
        cosangle = (L . A) / length(L);
        atten = pow(cosangle, beamdistribution) / (L . L);
        atten *= smoothstep(cosoutside, cosinside, cosangle);
        Cl = atten * intensity * lightcolor;
    }
}
