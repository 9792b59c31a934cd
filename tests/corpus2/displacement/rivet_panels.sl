/*
 * rivet_panels.sl -- riveted sheet-metal panels: recessed seams between
 * rectangular panels, a row of domed rivets along every seam, and a
 * slight "oil-can" bulge in the middle of each panel.
 *
 * Exercises: filteredpulse() and boxstep() from a header with
 * filterwidth() of s/t-derived coordinates, mod()/floor() panel
 * indexing, rivet spacing by mod() along the seam, ?: between
 * expressions, sqrt() dome profile, a panel-dependent random bulge
 * from cellnoise(float, float), P moved along a normalised N, then
 * N = calculatenormal(P), plus a bump-only switch.
 */
#include "aa_filters.h"

displacement rivet_panels(
    float Km = 0.01;
    float panelwidth = 0.25, panelheight = 0.125;
    float seamwidth = 0.006, seamdepth = 1;
    float rivetspacing = 0.02, rivetradius = 0.003, rivetinset = 0.01, rivetheight = 0.8;
    float bulge = 0.5;
    float bumponly = 0;)
{
    float ss = s / panelwidth, tt = t / panelheight;
    float col = floor(ss), row = floor(tt);
    float fs = ss - col, ft = tt - row;

    /* Seams: antialiased grooves at the panel borders. */
    float fws = filterwidth(ss), fwt = filterwidth(tt);
    uniform float sw = 0.5 * seamwidth / panelwidth;
    uniform float th = 0.5 * seamwidth / panelheight;
    float panel = filteredpulse(sw, 1 - sw, fs, fws) * filteredpulse(th, 1 - th, ft, fwt);
    float seam = 1 - panel;

    /* Rivets: along vertical seams at distance rivetinset, spaced along t. */
    float ds = min(fs, 1 - fs) * panelwidth;        /* distance to nearest vertical seam */
    float dt = min(ft, 1 - ft) * panelheight;       /* distance to nearest horizontal seam */
    float along_t = mod(t, rivetspacing) - rivetspacing / 2;
    float along_s = mod(s, rivetspacing) - rivetspacing / 2;
    float rv = sqrt((ds - rivetinset) * (ds - rivetinset) + along_t * along_t);
    float rh = sqrt((dt - rivetinset) * (dt - rivetinset) + along_s * along_s);
    float r = (ds < dt) ? rv : rh;
    float rivet = (r < rivetradius) ? sqrt(1 - (r / rivetradius) * (r / rivetradius)) : 0;
    rivet *= 1 - boxstep(rivetradius, r, filterwidth(r));

    /* Oil-can bulge: a random height per panel, zero at the edges. */
    float pb = bulge * (float cellnoise(col, row) - 0.5);
    float dome = 16 * fs * (1 - fs) * ft * (1 - ft);

    float h = -seamdepth * seam + rivetheight * rivet + pb * dome;
    normal Nn = normalize(N);
    point Pd = P + Km * h * Nn;
    if (bumponly != 0) {
        N = calculatenormal(Pd);
    } else {
        P = Pd;
        N = calculatenormal(P);
    }
}
