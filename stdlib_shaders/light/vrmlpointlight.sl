/*
 * vrmlpointlight.sl -- the VRML 97 PointLight node (ISO/IEC 14772-1,
 * sec. 6.36, and the lighting model of sec. 4.14.5); this library's own.
 *
 * A point light at "from" whose light is divided by
 * max(c0 + c1 d + c2 d^2, 1) at the distance d, VRML's attenuation (1 0 0,
 * the default, is no falloff), and reaches no farther than radius.  VRML's
 * ambientIntensity is not part of it (the VRML reader adds an ambient light).
 *
 * Parameters:
 *   intensity            -- brightness of the light (1).
 *   lightcolor           -- colour of the light (1, white).
 *   from                 -- position of the light (shader origin).
 *   constantattenuation  -- c0 (1).
 *   linearattenuation    -- c1 (0).
 *   quadraticattenuation -- c2 (0).
 *   radius               -- the farthest point lit (100).
 *   __category           -- the categories it belongs to, comma separated
 *                           (""; the VRML 1.0 reader scopes lights so).
 */
light vrmlpointlight(float intensity = 1; color lightcolor = 1;
                     point from = point "shader" (0, 0, 0);
                     float constantattenuation = 1;
                     float linearattenuation = 0;
                     float quadraticattenuation = 0;
                     float radius = 100;
                     string __category = "";)
{
    float d, atten;

    illuminate(from) {
        d = length(L);
        atten = 1 / max(constantattenuation
                        + d * (linearattenuation + d * quadraticattenuation), 1);
        if (d > radius)
            atten = 0;
        Cl = atten * intensity * lightcolor;
    }
}
