/* pc_corrupt.c: a PC program of the tests' own, in C (clients/c), that streams a short jog and
 * corrupts one record the first time it writes it: the card must reject it and the client's
 * go-back-N send it again (tests/test_serve.py).
 *     pc_corrupt ATTACH_FOLDER SEQ BIT */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "cnct_client.h"

static uint32_t flip_seq, flip_bit, flipped;

static void corrupt(uint32_t seq, uint16_t *words, size_t n, void *ctx) {
    (void)ctx;
    if (seq != flip_seq || flipped || flip_bit / 16 >= n) return;
    words[flip_bit / 16] ^= (uint16_t)(1u << (flip_bit % 16));
    flipped = 1;
}

/* a 60 mm X move within the axis's limits (0.4 m/s, 2 m/s^2: it never reaches 0.4, a triangle),
 * stretched to whole 1 ms periods */
static uint32_t add_move(cnct_stream *s, double x) {
    double a = 2.0 / 0.06, t_acc = sqrt(1.0 / a), v = a * t_acc, t_flat = 0.0, duration = 2 * t_acc + t_flat;
    uint32_t periods = (uint32_t)ceil(duration / 0.001 - 1e-9);
    double k = periods * 0.001 / duration, end[6] = {x, 0, 0, 0, 0, 0};
    cnct_record r;
    if (cnct_move(&r, end, t_acc * k, t_flat * k, v / k, a / (k * k), periods) != 0 || cnct_stream_add(s, &r) != 0)
        exit(1);
    cnct_record_free(&r);
    return periods;
}

int main(int argc, char **argv) {
    cnct_card card;
    cnct_stream stream;
    cnct_record r;
    if (argc != 4 || cnct_open(&card, argv[1], 30.0) != 0) return 1;
    flip_seq = (uint32_t)atoi(argv[2]);
    flip_bit = (uint32_t)atoi(argv[3]);
    cnct_stream_init(&stream, &card, 4096, 0);
    stream.corrupt = corrupt;
    uint32_t periods = add_move(&stream, 0.06) + add_move(&stream, 0.0);
    if (cnct_dwell(&r, 200) != 0 || cnct_stream_add(&stream, &r) != 0) return 1;
    cnct_record_free(&r);
    if (cnct_end_of_program(&r) != 0 || cnct_stream_add(&stream, &r) != 0) return 1;
    cnct_record_free(&r);
    stream.complete = 1;
    cnct_attach(&card, periods + 200);
    if (cnct_stream_run(&stream, NULL, NULL) != 0) return 1;
    uint16_t state, fault;
    if (cnct_end_state(&card, &state, &fault) != 0) return 1;
    printf("ended %u %u sent %zu again %u\n", state, fault, stream.next_index, stream.retransmitted);
    cnct_stream_free(&stream);
    cnct_close(&card);
    return state == CNCT_DSP_STATE_FINISHED ? 0 : 3;
}
