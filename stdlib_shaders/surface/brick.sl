/*
 * brick.sl -- after the "brick" shader of Upstill's "The RenderMan
 * Companion" (ch. 16), with per-brick colour variation as in Apodaca &
 * Gritz, "Advanced RenderMan" (ch. 12).
 *
 * Running-bond brickwork in the texture coordinates (s, t): rows of bricks
 * brickwidth by brickheight (mortar included), every other row shifted by
 * half a brick, separated by mortar lines mortarthickness wide.  Each
 * brick's colour is brickcolor varied by cellnoise of its row and column
 * (so whole bricks differ) and by noise within the brick (mottling); the
 * mortar gets a little noise too.  Edges are point-sampled (no filtering:
 * the JIT does not compile derivatives yet), slightly softened by
 * smoothstep.  Lit like "matte".
 *
 * Parameters:
 *   Ka              -- scale applied to the ambient light (1).
 *   Kd              -- scale applied to the diffuse reflection (1).
 *   brickcolor      -- mean colour of the bricks (.5, .15, .1).
 *   mortarcolor     -- colour of the mortar (.55, .55, .5).
 *   brickwidth      -- brick plus mortar width, in s (.25).
 *   brickheight     -- brick plus mortar height, in t (.08).
 *   mortarthickness -- width of the mortar lines, in s and t units (.01).
 *   variation       -- how much bricks differ from one another, 0 to 1 (.25).
 *   mottle          -- strength of the noise within each brick (.2).
 */
surface brick(float Ka = 1; float Kd = 1;
              color brickcolor = color(.5, .15, .1);
              color mortarcolor = color(.55, .55, .5);
              float brickwidth = .25; float brickheight = .08;
              float mortarthickness = .01;
              float variation = .25; float mottle = .2;)
{
    normal Nf = faceforward(normalize(N), I);
    uniform float mw = .5 * mortarthickness / brickwidth;
    uniform float mh = .5 * mortarthickness / brickheight;
    float ss = s / brickwidth, tt = t / brickheight;
    float row = floor(tt), col, sb, tb, inbrick, n;
    color Cb, Cm, Ct;

    /* Shift every other row by half a brick. */
    if (mod(row, 2) >= 1)
        ss += .5;
    col = floor(ss);
    sb = ss - col;
    tb = tt - row;

    /* 1 inside a brick, 0 in the mortar. */
    inbrick = (smoothstep(0, mw, sb) - smoothstep(1 - mw, 1, sb))
            * (smoothstep(0, mh, tb) - smoothstep(1 - mh, 1, tb));

    /* A colour per brick, then mottling within it. */
    Cb = brickcolor * (1 + variation * (2 * (color cellnoise(col, row)) - 1));
    n = float noise(point(ss * 6, tt * 3, col + 13 * row));
    Cb *= 1 + mottle * (2 * n - 1);
    Cm = mortarcolor * (1 + .15 * (2 * float noise(s * 80, t * 80) - 1));
    Ct = mix(Cm, Cb, inbrick);

    Oi = Os;
    Ci = Os * Ct * (Ka * ambient() + Kd * diffuse(Nf));
}
