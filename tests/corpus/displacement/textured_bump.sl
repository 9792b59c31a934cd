/*
 * textured_bump.sl -- bump mapping from a grey-scale height texture,
 * differentiating the texture by finite differences in (s, t) sized to
 * the local filter width, then tilting the normal along the surface
 * tangents (a classic pre-displacement bump).
 *
 * Exercises: texture() on a channel ("name"[0]) with "blur" and "width",
 * Du(), Dv() and Deriv() of s and t, du/dv, area(P), dPdu/dPdv tangents,
 * the cross product ^, normalize(), a bump-only displacement (N changes,
 * P does not), string parameter test, and early outs with if/else.
 */
displacement textured_bump(
    float Km = .1;
    string bumpmap = "";
    float blur = 0;
    float invert = 0;)
{
    normal Nn = normalize(N);

    if (bumpmap != "") {
        /* Finite-difference steps in s and t, from the pixel footprint. */
        float ds = max(abs(Du(s) * du) + abs(Dv(s) * dv), 1.0e-4);
        float dt = max(abs(Du(t) * du) + abs(Dv(t) * dv), 1.0e-4);

        float h0 = float texture(bumpmap[0], s, t, "blur", blur);
        float hs = float texture(bumpmap[0], s + ds, t, "blur", blur, "width", 1);
        float ht = float texture(bumpmap[0], s, t + dt, "blur", blur, "width", 1);
        float flip = (invert > 0) ? -1 : 1;

        /* Height gradient along s and t, then along the surface tangents. */
        float dhds = flip * (hs - h0) / ds;
        float dhdt = flip * (ht - h0) / dt;
        vector Ts = normalize(dPdu) * abs(Deriv(s, u));
        vector Tt = normalize(dPdv) * abs(Deriv(t, v));

        /* Bump strength shrinks on tiny micropolygons (area in current space). */
        float footprint = sqrt(area(P));
        float strength = Km * smoothstep(0, 1.0e-3, footprint);

        normal Nb = Nn - strength * (dhds * (Nn ^ Tt) - dhdt * (Nn ^ Ts));
        N = normalize(Nb);
    } else {
        N = Nn;
    }
}
