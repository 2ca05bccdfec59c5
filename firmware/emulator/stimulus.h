// Stimulus stream: timestamped physical truth for the MPU-6000 model (format: README.md).
#pragma once

#include <stdio.h>

#include "mpu6000.h"

#define STIM_MAGIC "IMUSTIM1"
#define STIM_FIELDS 8  // t_s, fx, fy, fz [m/s^2], wx, wy, wz [deg/s], temp_c

typedef struct stim_rec {
    double t;
    mpu_truth_t v;
} stim_rec_t;

#define STIM_BACK 8192  // records kept for stim_back (the DLPF looks up to 19 ms back)

typedef struct stim {
    FILE *fp;          // NULL: constant level (Z up, at rest, 25 degC)
    stim_rec_t back[STIM_BACK];  // the records before cur, newest last (ring)
    unsigned back_n, back_head;
    int have_cur, have_next, eof;
    stim_rec_t cur, next;
    unsigned long records;
    char error[200];
} stim_t;

// path NULL = constant level; "-" = standard input. Returns 0 or -1 (error in s->error).
int stim_open(stim_t *s, const char *path);
// Sample-and-hold value at time t (seconds since the emulator started).
// Returns 1 while the stream covers t, 0 once t is past the last record of an ended stream
// (the last value is still returned in *out).
int stim_at(stim_t *s, double t, mpu_truth_t *out);
// Sample-and-hold value at an earlier time t (<= the last stim_at's), from the records kept
// (STIM_BACK); before the oldest kept: the oldest.
void stim_back(stim_t *s, double t, mpu_truth_t *out);
void stim_close(stim_t *s);
