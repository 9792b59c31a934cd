/*
 * string_frames.sl -- an animated texture-sequence surface: the texture
 * name is built from a base name, the frame number and a variant, with
 * layer names chosen from an array and channels picked by string
 * switches; everything degrades gracefully when names are empty.
 *
 * Exercises: format("%s.%d.tx", name, frame) and "%04d" padding with
 * uniform floats, concat() of several strings, match() with anchors,
 * alternation and character classes, == / != on string parameters,
 * arrays of strings (parameter and local), string locals assigned in
 * if/else, textureinfo() with "resolution" into a float[2], texture()
 * with "blur"/"width"/"filter", texture with a channel index
 * name[channel], shadername(), and printf with %s.
 */
#define NLAYERS 3

/* Name of one frame of a sequence: base.layer.NNNN.tx */
string frame_name(string base, layer; float frame, pad)
{
    string num = (pad > 0) ? format("%04d", frame) : format("%d", frame);
    return concat(base, ".", layer, ".", num, ".tx");
}

surface string_frames(
    float Ka = 1, Kd = 1;
    string basename = "plate";
    string layers[NLAYERS] = {"diffuse", "dirt", "mask"};
    uniform float frame = 1, startframe = 1, cycle = 0;
    float pad = 1;
    string channelmode = "rgb";     /* "rgb", "red", "alpha" or "luma" */
    string filtername = "gaussian";
    float blur = 0;
    float verbose = 0;)
{
    /* Optional looping of the frame range. */
    uniform float f = (cycle > 0) ? startframe + mod(frame - startframe, cycle) : frame;

    string names[NLAYERS];
    uniform float i;
    for (i = 0; i < NLAYERS; i += 1)
        names[i] = (basename != "") ? frame_name(basename, layers[i], f, pad) : "";

    /* A plain "%s.%d.tx" name for the legacy single-file case. */
    string legacy = format("%s.%d.tx", basename, f);
    if (match("^(plate|bg)[0-9]*$", basename) == 0)
        legacy = "";

    color Ct = Cs;
    string diffname = names[0];
    string dirtname = names[1];
    string maskname = names[2];
    if (diffname == "" && legacy != "")
        diffname = legacy;

    if (diffname != "") {
        float res[2] = {0, 0};
        float blurfix = blur;
        if (textureinfo(diffname, "resolution", res) != 0 && res[0] > 0)
            blurfix = max(blur, 0.5 / res[0]);
        if (channelmode == "rgb")
            Ct = color texture(diffname, s, t, "blur", blurfix, "filter", filtername);
        else if (channelmode == "red")
            Ct = float texture(diffname[0], s, t, "blur", blurfix);
        else if (channelmode == "alpha")
            Ct = float texture(diffname[3], s, t, "blur", blurfix, "width", 1);
        else {
            color c = color texture(diffname, s, t, "blur", blurfix);
            Ct = 0.3 * comp(c, 0) + 0.59 * comp(c, 1) + 0.11 * comp(c, 2);
        }
    }

    if (dirtname != "" && match("dirt|grime", dirtname) != 0)
        Ct *= 1 - 0.5 * float texture(dirtname[0], s, t);

    float opacity = 1;
    if (maskname != "")
        opacity = float texture(maskname[0], s, t);

    if (verbose != 0)
        printf("%s: frame %s, diffuse \"%s\"\n", shadername(), format("%g", f), diffname);

    normal Nf = faceforward(normalize(N), I);
    Oi = Os * opacity;
    Ci = Oi * Ct * (Ka * ambient() + Kd * diffuse(Nf));
}
