/*
 * vrmlspotlight.sl -- the VRML 97 SpotLight node (ISO/IEC 14772-1,
 * sec. 6.44, and the lighting model of sec. 4.14.5); this library's own.
 *
 * A light at "from" aimed at "to" that lights the cone of half-angle
 * cutoffangle: fully within beamwidth of its axis, then falling linearly in
 * the angle to zero at cutoffangle (a beamwidth at least as wide as the cone
 * lights it evenly).  Its light is divided by max(c0 + c1 d + c2 d^2, 1) at
 * the distance d and reaches no farther than radius, as a VRML PointLight's.
 *
 * Parameters:
 *   intensity            -- brightness of the light (1).
 *   lightcolor           -- colour of the light (1, white).
 *   from                 -- position of the light (shader origin).
 *   to                   -- point the light is aimed at (shader (0,0,-1)).
 *   beamwidth            -- half-angle of the fully lit cone, radians (PI/2).
 *   cutoffangle          -- half-angle of the lit cone, radians (PI/4).
 *   constantattenuation  -- c0 (1).
 *   linearattenuation    -- c1 (0).
 *   quadraticattenuation -- c2 (0).
 *   radius               -- the farthest point lit (100).
 *   __category           -- the categories it belongs to, comma separated
 *                           (""; the VRML 1.0 reader scopes lights so).
 */
light vrmlspotlight(float intensity = 1; color lightcolor = 1;
                    point from = point "shader" (0, 0, 0);
                    point to = point "shader" (0, 0, -1);
                    float beamwidth = 1.570796;
                    float cutoffangle = 0.785398;
                    float constantattenuation = 1;
                    float linearattenuation = 0;
                    float quadraticattenuation = 0;
                    float radius = 100;
                    string __category = "";)
{
    uniform vector A = (to - from) / length(to - from);
    float d, angle, spot, atten;

    illuminate(from, A, cutoffangle) {
        d = length(L);
        angle = acos(clamp((L . A) / d, -1, 1));
        spot = 1;
        if (angle >= cutoffangle)
            spot = 0;
        else if (beamwidth < cutoffangle && angle > beamwidth)
            spot = (angle - cutoffangle) / (beamwidth - cutoffangle);
        atten = 1 / max(constantattenuation
                        + d * (linearattenuation + d * quadraticattenuation), 1);
        if (d > radius)
            atten = 0;
        Cl = spot * atten * intensity * lightcolor;
    }
}
