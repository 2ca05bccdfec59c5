// Stimulus stream reader (sample-and-hold). See stimulus.h and README.md.
#include "stimulus.h"

#include <string.h>
#include <sys/stat.h>

static const mpu_truth_t REST = {{0.0, 0.0, 9.80665}, {0.0, 0.0, 0.0}, 25.0};

static int read_rec(stim_t *s, stim_rec_t *r) {
    double d[STIM_FIELDS];
    if (fread(d, sizeof(double), STIM_FIELDS, s->fp) != STIM_FIELDS) return 0;
    // little-endian float64 on disk; this program only builds on little-endian hosts
    r->t = d[0];
    for (int i = 0; i < 3; i++) {
        r->v.f[i] = d[1 + i];
        r->v.w[i] = d[4 + i];
    }
    r->v.temp = d[7];
    s->records++;
    return 1;
}

int stim_open(stim_t *s, const char *path) {
    memset(s, 0, sizeof *s);
    if (!path) return 0;
    s->fp = strcmp(path, "-") == 0 ? stdin : fopen(path, "rb");
    if (!s->fp) {
        snprintf(s->error, sizeof s->error, "cannot open stimulus %s", path);
        return -1;
    }
    // On a pipe, read unbuffered: every byte the emulator has not used stays in the pipe, so
    // the writer (host/emulator.py SimStimulus) can tell from the pipe's fill level exactly how
    // far the emulated time has got, and a pipe that runs dry stops the emulation (read
    // blocks) instead of ending it. A stdio buffer would hide up to 4 KiB of records.
    struct stat st;
    if (fstat(fileno(s->fp), &st) == 0 && S_ISFIFO(st.st_mode)) setvbuf(s->fp, NULL, _IONBF, 0);
    unsigned char hdr[16];
    if (fread(hdr, 1, 16, s->fp) != 16 || memcmp(hdr, STIM_MAGIC, 8) != 0) {
        snprintf(s->error, sizeof s->error, "%s: not a stimulus stream (no %s header)", path,
                 STIM_MAGIC);
        return -1;
    }
    unsigned nfields = hdr[8] | hdr[9] << 8 | hdr[10] << 16 | (unsigned)hdr[11] << 24;
    if (nfields != STIM_FIELDS) {
        snprintf(s->error, sizeof s->error, "%s: %u fields per record, expected %d", path,
                 nfields, STIM_FIELDS);
        return -1;
    }
    if (!read_rec(s, &s->cur)) {
        snprintf(s->error, sizeof s->error, "%s: no records", path);
        return -1;
    }
    s->have_cur = 1;
    s->have_next = read_rec(s, &s->next);
    s->eof = !s->have_next;
    return 0;
}

int stim_at(stim_t *s, double t, mpu_truth_t *out) {
    if (!s->fp) {
        *out = REST;
        return 1;
    }
    while (s->have_next && s->next.t <= t) {
        s->back[s->back_head] = s->cur;
        s->back_head = (s->back_head + 1) % STIM_BACK;
        if (s->back_n < STIM_BACK) s->back_n++;
        s->cur = s->next;
        s->have_next = read_rec(s, &s->next);
        if (!s->have_next) s->eof = 1;
    }
    *out = s->cur.v;
    if (t < s->cur.t) *out = s->cur.v;  // before the first record: hold the first value
    return !(s->eof && !s->have_next && t > s->cur.t);
}

void stim_back(stim_t *s, double t, mpu_truth_t *out) {
    if (!s->fp) {
        *out = REST;
        return;
    }
    if (t >= s->cur.t || !s->back_n) {
        *out = s->cur.v;
        return;
    }
    unsigned k = 0;
    const stim_rec_t *r = &s->cur;
    while (k < s->back_n) {
        r = &s->back[(s->back_head + STIM_BACK - 1 - k) % STIM_BACK];
        if (r->t <= t) break;
        k++;
    }
    *out = r->v;
}

void stim_close(stim_t *s) {
    if (s->fp && s->fp != stdin) fclose(s->fp);
    s->fp = NULL;
}
