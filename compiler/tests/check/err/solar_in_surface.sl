// expect: E0112
// solar is a light-shader statement; a surface shader cannot use it.
surface solar_in_surface(vector dir = vector "world" (0, -1, 0);)
{
    Ci = 0;
    solar(dir, 0) {
        Ci = Cs;
    }
    Oi = Os;
}
