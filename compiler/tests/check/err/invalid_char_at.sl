// expect: E0020
// '@' is not a character of the shading language outside strings and
// comments.
surface invalid_char_at(float Kd = 1;)
{
    Ci = Cs @ Kd;
    Oi = Os;
}
