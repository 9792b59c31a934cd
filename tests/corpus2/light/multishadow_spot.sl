/*
 * multishadow_spot.sl -- a spotlight that combines several shadow maps
 * whose file names are built at render time from a base name, a list of
 * suffixes and the frame number, e.g. "key.front.0042.shd".
 *
 * Exercises: arrays of strings as shader parameters and locals, string
 * array initialisers with {}, format() with %s and %d on uniform floats,
 * concat() with three arguments, match() against a regular expression,
 * string == and != comparisons, a uniform loop over a string array
 * feeding shadow() outside illuminate (Ps is global in lights), an
 * element of a string array used directly as the shadow() map name,
 * shadow() with "samples"/"blur"/"bias"/"width", the two-argument
 * form, ?: choosing between format() results, printf of strings, and
 * radians()/cos() spot cone shaping.
 */
light multishadow_spot(
    float intensity = 1;
    color lightcolor = 1;
    point from = point "shader" (0, 0, 0);
    point to = point "shader" (0, 0, 1);
    float coneangle = 30, conedeltaangle = 5, beamdistribution = 2;
    string mapbase = "key";
    string mapsuffixes[3] = {"front", "back", "hair"};
    uniform float nmaps = 3;
    uniform float frame = 1;
    uniform float padframe = 1;
    string mapext = "shd";
    float blur = 0.005, samples = 16, bias = 0.02;
    float verbose = 0;
    uniform string __category = "spot";
    output uniform float __nonspecular = 0;)
{
    uniform string names[3] = {"", "", ""};
    uniform float i;
    uniform float count = clamp(nmaps, 0, 3);

    /* Build every map name once, at uniform level. */
    for (i = 0; i < count; i += 1) {
        uniform string framestr = (padframe != 0) ? format("%04d", frame) : format("%d", frame);
        names[i] = concat(mapbase, ".", concat(mapsuffixes[i], ".", framestr, ".", mapext));
        /* A suffix of "none" or anything starting with '-' disables that slot. */
        if (mapsuffixes[i] == "none" || match("^-", mapsuffixes[i]) != 0)
            names[i] = "";
        if (verbose > 0)
            printf("multishadow_spot: map %d is \"%s\"\n", i, names[i]);
    }

    uniform vector A = normalize(to - from);
    uniform float outer = radians(coneangle);
    uniform float inner = radians(coneangle - conedeltaangle);

    /*
     * Combine the maps before the light loop: Ps is available anywhere in
     * a light shader, and this keeps the loop counter uniform.
     */
    float lit = 1;
    for (i = 0; i < count; i += 1) {
        if (names[i] != "") {
            float occl;
            if (match("hair", names[i]) != 0)
                occl = shadow(names[i], Ps);        /* hair maps: no filtering */
            else
                occl = shadow(names[i], Ps, "samples", samples, "blur", blur,
                              "bias", bias, "width", 1);
            lit *= 1 - occl;
        }
    }

    illuminate(from, A, outer) {
        float cosangle = (L . A) / length(L);
        float atten = pow(cosangle, beamdistribution) / (L . L);
        atten *= smoothstep(cos(outer), cos(inner), cosangle);
        Cl = intensity * lightcolor * atten * lit;
    }
}
