#version 450
// Radix-2 pass of the Stockham FFT (see fft_common.glsl, kernels/fft.cpp).
#define RADIX 2
#include "fft_common.glsl"
