// expect: E0112
// illuminate is a light-shader statement; a surface shader cannot use it.
surface illuminate_in_surface(point from = point "shader" (0, 0, 0);)
{
    Ci = 0;
    illuminate(from) {
        Ci = Cs;
    }
    Oi = Os;
}
