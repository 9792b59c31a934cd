// expect: E0108
// An if condition must be a relation (or float); a string is not allowed.
// Compare it instead: if (mapname != "").
surface string_condition(string mapname = "";)
{
    Ci = Cs;
    if (mapname)
        Ci = color texture(mapname, s, t);
    Oi = Os;
}
