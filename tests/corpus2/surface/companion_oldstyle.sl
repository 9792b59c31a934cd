/*
 * companion_oldstyle.sl -- a wood-and-paint sign written in the older
 * style of early RenderMan Companion-era shaders: "point" used for every
 * direction and normal, a hand-written light loop, the four-corner
 * texture() form, C++ comments, and loops steered with continue and
 * break n.
 *
 * Exercises: point variables holding normals and directions (implicit
 * point/vector/normal interchange), faceforward with three arguments,
 * the 8-coordinate texture(name, s0,t0, s1,t1, s2,t2, s3,t3) lookup,
 * // comments, for loops with continue, nested loops left with
 * "break 2", Deriv(), a varying array local, area(P), and
 * illuminance(P, N, angle) accumulating a hand-made Phong term.
 */

surface companion_oldstyle(
    float Ka = 1, Kd = 0.7, Ks = 0.3, roughness = 0.25;
    string signtexture = "";
    color paintcolor = color(0.9, 0.85, 0.6), woodcolor = color(0.45, 0.28, 0.12);
    float ringscale = 15, grainy = 1;
    float letterrows = 3;)
{
    point PP = transform("shader", P);          // old habit: everything is a point
    point NN = normalize(N);
    point Nf = faceforward(NN, I, Ng);
    point V = -normalize(I);

    // Rings around the shader-space y axis, slightly wobbly.
    float r = sqrt(xcomp(PP) * xcomp(PP) + zcomp(PP) * zcomp(PP)) * ringscale;
    r += 0.5 * noise(PP * 3);
    float ring = mod(r, 1);
    ring = smoothstep(0, 0.8, ring) - smoothstep(0.83, 1, ring);
    float grain = noise(point(xcomp(PP) * 40, ycomp(PP) * 2, zcomp(PP) * 40));
    color wood = woodcolor * (0.7 + 0.3 * ring) * (1 - 0.2 * grainy * grain);

    // Paint coverage, looked up over the whole sample footprint when possible.
    float paint = 0;
    if (signtexture != "") {
        float ds = Deriv(s, u) * du, dt = Deriv(t, v) * dv;
        paint = float texture(signtexture[0], s, t, s + ds, t, s, t + dt, s + ds, t + dt);
    } else {
        // No texture: a few horizontal bars standing in for lettering.
        float rowv[4];
        float i, j;                              // varying: the break below is varying
        for (i = 0; i < 4; i += 1)
            rowv[i] = 0;
        for (i = 0; i < letterrows; i += 1) {
            if (mod(i, 2) == 1)
                continue;                        // skip every other row
            for (j = 0; j < 8; j += 1) {
                float x0 = j / 8 + 0.02, x1 = (j + 1) / 8 - 0.02;
                float y0 = (i + 0.3) / letterrows, y1 = (i + 0.7) / letterrows;
                if (s >= x0 && s < x1 && t >= y0 && t < y1) {
                    rowv[min(i, 3)] = 1;
                    break 2;                     // done with both loops for this point
                }
            }
        }
        paint = max(max(rowv[0], rowv[1]), max(rowv[2], rowv[3]));
    }

    // Paint chips where the wood grain is open; fine grain fades with footprint.
    float footprint = sqrt(area(P));
    float chip = smoothstep(0.6, 0.7, grain) * (1 - smoothstep(0.01, 0.05, footprint));
    color Ct = mix(wood, paintcolor, paint * (1 - chip));

    // Hand-made diffuse and Phong in one loop.
    color diff = 0, spec = 0;
    illuminance(P, Nf, PI / 2) {
        point Ln = normalize(L);
        diff += Cl * (Ln . Nf);
        point R = reflect(-Ln, Nf);
        spec += Cl * pow(max(0, R . V), 1 / roughness);
    }

    Oi = Os;
    Ci = Os * (Ct * (Ka * ambient() + Kd * diff) + Ks * paint * spec);
}
