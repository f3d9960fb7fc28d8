#version 450
// Radix-5 pass of the Stockham FFT (see fft_common.glsl, kernels/fft.cpp).
#define RADIX 5
#include "fft_common.glsl"
