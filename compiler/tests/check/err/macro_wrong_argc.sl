// expect: E0007
// SQR takes one argument but is invoked with two.
#define SQR(x) ((x) * (x))

surface macro_wrong_argc(float gain = 2;)
{
    Ci = Cs * SQR(gain, 2);
    Oi = Os;
}
