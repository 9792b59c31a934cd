// expect: E0020
// '$' may not appear in an identifier (or anywhere in code).
surface invalid_char_dollar()
{
    float $gain = 2;
    Ci = Cs * $gain;
    Oi = Os;
}
