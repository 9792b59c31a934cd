// expect: E0104
// pow() takes two arguments; no overload accepts one.
surface builtin_bad_arg_count(float gain = 2;)
{
    Ci = Cs * pow(gain);
    Oi = Os;
}
