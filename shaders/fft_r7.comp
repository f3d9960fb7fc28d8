#version 450
// Radix-7 pass of the Stockham FFT (see fft_common.glsl, kernels/fft.cpp).
#define RADIX 7
#include "fft_common.glsl"
