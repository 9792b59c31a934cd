// expect: E0117
// "gain" is a plain float, not an array, so it cannot be indexed.
surface index_float()
{
    float gain = 2;
    Ci = Cs * gain[0];
    Oi = Os;
}
