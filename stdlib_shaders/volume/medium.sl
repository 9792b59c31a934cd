/*
 * medium.sl -- a homogeneous participating medium for Interior (or
 * Atmosphere) use; this library's own.
 *
 * Over a ray segment of length d = length(I) the medium lets through
 * T = exp(-density * absorption * d) per colour channel and glows with
 * its own colour (mediumcolor, standing in for light scattered towards
 * the viewer) by 1 - T.  It is composited over what the segment reaches:
 * Ci = T Ci + (1 - T) mediumcolor, Oi = 1 - T (1 - Oi), so whatever lies
 * behind a transparent surface is attenuated by T too.
 *
 * Parameters:
 *   density     -- extinction per unit length (1).
 *   absorption  -- relative extinction per colour channel (1, 1, 1).
 *   mediumcolor -- colour the medium glows with (0, black: purely
 *                  absorbing).
 */
volume medium(float density = 1; color absorption = 1; color mediumcolor = 0;)
{
    float d = length(I);
    color T = exp(-density * d * absorption);
    Ci = T * Ci + (1 - T) * mediumcolor;
    Oi = 1 - T * (1 - Oi);
}
