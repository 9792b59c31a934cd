/*
 * rusty_metal.sl -- painted or bare metal with patches of rust: an fBm
 * mask decides where rust has formed, rust is rough, orange-brown and
 * matte, and the surrounding metal keeps its shine.  The rust style is a
 * compile-time choice.
 *
 * Exercises: a shader-local #define chosen by #if / #elif / #else on an
 * integer macro, defined() in #if, a function-like macro calling another
 * macro (RUSTMASK uses snoise), filteredfBm and fBm from noises.h,
 * filterwidthp(), MaterialRoughMetal and MaterialMatte from material.h,
 * blending two materials with mix(), and an output varying parameter.
 */
#ifndef RUST_STYLE
#define RUST_STYLE 2
#endif

#include "noises.h"
#include "material.h"

#if RUST_STYLE == 1
#define RUST_CONTRAST .05
#elif RUST_STYLE == 2 && defined(NOISES_H)
#define RUST_CONTRAST .15
#else
#define RUST_CONTRAST .3
#endif

/* Rust coverage from a noise value n, thresholded at "amount". */
#define RUSTMASK(n, amount) smoothstep((amount) - RUST_CONTRAST, (amount) + RUST_CONTRAST, (n))

surface rusty_metal(
    float Ka = 1, Ks = .8, roughness = .08;
    float Kdrust = .9;
    float rustamount = .55, rustfreq = 2;
    color metalcolor = color(.7, .72, .75);
    color rustcolor = color(.45, .2, .07);
    color rustdark = color(.2, .08, .03);
    output varying float rustmask = 0;)
{
    point PP = transform("shader", P) * rustfreq;
    float fw = filterwidthp(PP);
    normal Nf = faceforward(normalize(N), I);

    /* Rust grows where the (filtered) fBm is high; pits make it patchy. */
    float n = .5 + .5 * filteredfBm(PP, fw, 6, 2, .55);
    n += .1 * snoise(PP * 9);
    rustmask = RUSTMASK(n, 1 - rustamount);

    /* Inside the rust, vary between light and dark oxide. */
    float variety = .5 + .5 * fBm(PP * 5, 3, 2, .5);
    color Crust = mix(rustcolor, rustdark, smoothstep(.3, .7, variety));

    color metal = MaterialRoughMetal(Nf, metalcolor, Ka, Ks, roughness);
    color rust = MaterialMatte(Nf, Crust, Ka, Kdrust);

    Oi = Os;
    Ci = Os * mix(metal, rust, rustmask);
}
