#version 450
// Radix-16 pass of the Stockham FFT (see fft_common.glsl, kernels/fft.cpp).
#define RADIX 16
#include "fft_common.glsl"
