#version 450
// Radix-8 pass of the Stockham FFT (see fft_common.glsl, kernels/fft.cpp).
#define RADIX 8
#include "fft_common.glsl"
