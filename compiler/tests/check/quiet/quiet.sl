#include "library.h"

surface quiet(float Kd = 1;) {
    float noisy = 1;
#pragma nolint
    float quieted = 2;
    Ci = library_weight(Kd, 0);
}
