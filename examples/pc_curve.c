/* pc_curve.c: a PC program of your own, in C, that streams a NURBS circle and a few moves to the
 * twin's card through its whiteboard (clients/c; nothing of the twin is linked in).
 *
 *     cc -O2 -std=c11 -Iclients/c examples/pc_curve.c clients/c/cnct_client.c -lm -o pc_curve
 *     cnc-twin serve nurbs_circle --attach /tmp/circle &   # the card and the machine, waiting
 *     ./pc_curve /tmp/circle                               # this program: the PC side
 *
 * It moves from home to the circle's start (a synchronised trapezoid within the axes' limits, the
 * feed capped along X Y Z), sends the circle (radius 40 mm, 270 mm below home: an exact rational
 * NURBS, degree 2, nine control points) and one S-curve block along all of it at 6 m/min, then
 * moves home. The machine's figures below are the bundled machine's (models/polisher.yaml). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "cnct_client.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

#define PERIOD 0.001        /* interpolation period [s] */
#define V_MAX 0.4           /* X, Y, Z velocity limit [m/s] */
#define A_MAX 2.0           /* X, Y, Z acceleration limit [m/s^2] */
#define RADIUS 0.04         /* [m] */
#define DEPTH (-0.27)       /* the circle's Z [m] */
#define FEED 0.1            /* along the circle [m/s] */
#define APPROACH_FEED 0.2   /* home <-> circle [m/s] */
#define PATH_ACCEL 2.0      /* [m/s^2] */
#define PATH_JERK 50.0      /* [m/s^3] */

static uint32_t whole_periods(double seconds) {
    double n = ceil(seconds / PERIOD - 1e-9);
    return n < 1.0 ? 1u : (uint32_t)n;
}

/* A synchronised trapezoid move from `from` to `to` (X Y Z only here), its record and periods. */
static uint32_t plan_move(cnct_stream *s, const double from[6], const double to[6], double feed) {
    double v = INFINITY, a = INFINITY, xyz_sq = 0.0;
    for (int i = 0; i < 3; i++) {
        double d = fabs(to[i] - from[i]);
        if (d == 0.0) continue;
        if (V_MAX / d < v) v = V_MAX / d;
        if (A_MAX / d < a) a = A_MAX / d;
        xyz_sq += d * d;
    }
    if (isinf(v)) return 0;
    if (feed / sqrt(xyz_sq) < v) v = feed / sqrt(xyz_sq);
    double t_acc, t_flat, v_peak;
    if (v * v / a >= 1.0) {
        t_acc = sqrt(1.0 / a);
        t_flat = 0.0;
        v_peak = a * t_acc;
    } else {
        t_acc = v / a;
        t_flat = 1.0 / v - t_acc;
        v_peak = v;
    }
    double duration = 2.0 * t_acc + t_flat;
    uint32_t periods = whole_periods(duration);
    double k = periods * PERIOD / duration;
    cnct_record r;
    if (cnct_move(&r, to, t_acc * k, t_flat * k, v_peak / k, a / (k * k), periods) != 0 || cnct_stream_add(s, &r) != 0)
        exit(1);
    cnct_record_free(&r);
    return periods;
}

static uint32_t add_dwell(cnct_stream *s, double seconds) {
    cnct_record r;
    uint32_t n = whole_periods(seconds);
    if (cnct_dwell(&r, n) != 0 || cnct_stream_add(s, &r) != 0) exit(1);
    cnct_record_free(&r);
    return n;
}

int main(int argc, char **argv) {
    if (argc != 2) {
        fprintf(stderr, "usage: %s ATTACH_FOLDER (the folder cnc-twin serve printed)\n", argv[0]);
        return 2;
    }
    cnct_card card;
    cnct_stream stream;
    cnct_record r;
    if (cnct_open(&card, argv[1], 30.0) != 0) {
        perror(argv[1]);
        return 1;
    }
    cnct_stream_init(&stream, &card, 4096, 0);

    const double home[6] = {0, 0, 0, 0, 0, 0}, start[6] = {RADIUS, 0, DEPTH, 0, 0, 0};
    const double w = sqrt(0.5), held[3] = {0, 0, 0};
    const double knots[12] = {0, 0, 0, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1, 1, 1};
    const double weights[9] = {1, w, 1, w, 1, w, 1, w, 1};
    const double corner[9][2] = {{1, 0}, {1, 1}, {0, 1}, {-1, 1}, {-1, 0}, {-1, -1}, {0, -1}, {1, -1}, {1, 0}};
    double points[27];
    for (int i = 0; i < 9; i++) {
        points[3 * i] = RADIUS * corner[i][0];
        points[3 * i + 1] = RADIUS * corner[i][1];
        points[3 * i + 2] = DEPTH;
    }
    uint32_t periods = plan_move(&stream, home, start, APPROACH_FEED);
    periods += add_dwell(&stream, 0.1);
    if (cnct_curve_geometry(&r, 2, 9, knots, weights, points, held) != 0 || cnct_stream_add(&stream, &r) != 0) return 1;
    cnct_record_free(&r);
    /* the whole circle in one block: its length, at rest at both ends; about L / v + v / a + a / j long */
    double length = 2.0 * M_PI * RADIUS;
    uint32_t block = whole_periods(length / FEED + FEED / PATH_ACCEL + PATH_ACCEL / PATH_JERK);
    if (cnct_curve_block(&r, length, 0.0, FEED, 0.0, PATH_ACCEL, PATH_JERK, block) != 0
        || cnct_stream_add(&stream, &r) != 0)
        return 1;
    cnct_record_free(&r);
    periods += block + add_dwell(&stream, 0.1);
    periods += plan_move(&stream, start, home, APPROACH_FEED);
    periods += add_dwell(&stream, 0.2);
    if (cnct_end_of_program(&r) != 0 || cnct_stream_add(&stream, &r) != 0) return 1;
    cnct_record_free(&r);
    stream.complete = 1;

    cnct_attach(&card, periods);
    int rc = cnct_stream_run(&stream, NULL, NULL);
    uint16_t state = 0, fault = 0;
    int ended = cnct_end_state(&card, &state, &fault);
    if (rc != 0 || ended != 0) {
        fprintf(stderr, "the card's side ended without a word (the twin's run was cut short)\n");
        return 1;
    }
    if (state == CNCT_DSP_STATE_FINISHED)
        printf("card: finished; sent %zu records, %u again\n", stream.next_index, stream.retransmitted);
    else
        printf("card: state %u, fault %u\n", state, fault);
    cnct_stream_free(&stream);
    cnct_close(&card);
    return state == CNCT_DSP_STATE_FINISHED ? 0 : 3;
}
