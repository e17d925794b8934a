/* cnct_client.h: the PC side of the cnc-twin card, for your own PC program in C.
 *
 * Written against the documented protocol only (docs/pc-software.md); the addresses, codes and
 * payload layouts are those of cnct_whiteboard.h, generated from the twin's own layout definition.
 * Linux (POSIX shared memory through the attach folder, named pipes), C99 + GCC/Clang atomics.
 *
 * A session, against `cnc-twin serve SCENARIO` (which prints "attach: FOLDER"):
 *
 *     cnct_card card;
 *     cnct_stream stream;
 *     cnct_record r;
 *     if (cnct_open(&card, folder, 30.0) != 0) { perror(folder); return 1; }
 *     cnct_stream_init(&stream, &card, 4096, 0);
 *     cnct_move(&r, end, t_acc, t_flat, v_peak, accel, periods); cnct_stream_add(&stream, &r);
 *     cnct_end_of_program(&r); cnct_stream_add(&stream, &r);
 *     stream.complete = 1;
 *     cnct_attach(&card, periods);
 *     cnct_stream_run(&stream, NULL, NULL);    // answers every status until the run is over
 *     cnct_end_state(&card, &state, &fault);   // CNCT_DSP_STATE_FINISHED, or a fault
 *     cnct_stream_free(&stream); cnct_close(&card);
 *
 * Units: positions in m (linear) or rad (rotary), absolute machine coordinates, axes X Y Z A B C;
 * times in s; motion durations in interpolation periods. Functions returning int give 0 on
 * success and -1 with errno set on failure, unless they say otherwise. */
#ifndef CNCT_CLIENT_H
#define CNCT_CLIENT_H

#include <stddef.h>
#include <stdint.h>

#include "cnct_whiteboard.h"

typedef struct {
    volatile uint16_t *word;   /* the whole RAM, 16-bit words */
    size_t words;              /* its size [words] */
    int wake_fd, ring_fd;      /* doorbells: to_pc (read), to_dsp (write) */
    uint16_t last_seen;        /* the card's mailbox value last answered */
    unsigned spin_polls;       /* mailbox polls before sleeping on the doorbell (0: none; the PC
                                  answers status k while the card runs period k) */
} cnct_card;

/* Map FOLDER/whiteboard and open the doorbells, waiting up to timeout_s for the folder. Ignores
 * SIGPIPE if it has its default action (a ring after the twin's process ended fails with EPIPE). */
int cnct_open(cnct_card *card, const char *folder, double timeout_s);
void cnct_close(cnct_card *card);
/* Program length [periods] (0: unknown), version, magic, READY: the card's clock starts. */
void cnct_attach(cnct_card *card, uint32_t program_periods);
/* Wait for the next status: 1 with *out filled, 0 when the run is over (see cnct_end_state),
 * -1 when the card's side is gone (the twin's process ended: errno EPIPE). */
int cnct_wait_status(cnct_card *card, cnct_status *out);
/* After the run is over: the state and fault it ended with; -1 before. */
int cnct_end_state(const cnct_card *card, uint16_t *state, uint16_t *fault);
void cnct_begin(cnct_card *card);
void cnct_end(cnct_card *card, int all_sent, uint16_t wake_free);
uint32_t cnct_fifo_free(const cnct_card *card);
void cnct_fifo_write(cnct_card *card, const uint16_t *words, size_t n);

/* A command record before it is numbered. */
typedef struct {
    uint16_t type;
    uint16_t in_parts;         /* a curve: sent as GeometryPart records when longer than a chunk */
    uint32_t periods;          /* the motion it holds [periods] (what the look-ahead counts) */
    size_t words;              /* payload length [words] */
    uint16_t *payload;         /* malloc'd by the builders below; cnct_stream_add copies it */
} cnct_record;

int cnct_move(cnct_record *r, const double end[6], double t_acc, double t_flat, double v_peak, double accel,
              uint32_t periods);
int cnct_dwell(cnct_record *r, uint32_t periods);
int cnct_feed_override(cnct_record *r, double fraction);
int cnct_force_setpoint(cnct_record *r, double newtons);
int cnct_spindle(cnct_record *r, int on, double speed);
int cnct_mark(cnct_record *r, uint32_t number);
int cnct_end_of_program(cnct_record *r);
/* A NURBS path in axis space: n points (x y z, m), n weights, n + degree + 1 knots; A B C held. */
int cnct_curve_geometry(cnct_record *r, uint16_t degree, uint16_t n, const double *knots, const double *weights,
                        const double *points, const double held[3]);
/* One S-curve block along the last curve: length [m], speeds v0 vp v1 [m/s], a_max, j_max. */
int cnct_curve_block(cnct_record *r, double length, double v0, double vp, double v1, double a_max, double j_max,
                     uint32_t periods);
void cnct_record_free(cnct_record *r);

/* CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF): "123456789" gives 0x29B1. */
uint16_t cnct_crc16(const uint8_t *data, size_t n);

/* Streaming with the FIFO's flow control and go-back-N: as many records per exchange as the FIFO's
 * free words, the chunk and the look-ahead allow (a record longer than the chunk goes alone); when
 * the card reports a rejected record, from the sequence number it expects. */
typedef struct {
    cnct_card *card;
    uint32_t chunk_words;
    uint32_t lookahead_periods;   /* 0: no limit */
    int fifo_interrupt;           /* ask for no exchange before the next record fits (default 1) */
    int complete;                 /* set after the last record was added */
    uint16_t **encoded;           /* every record on the wire, numbered from 1 */
    size_t *lengths;
    uint64_t *cumulative;         /* motion periods before each record */
    size_t count, capacity, next_index;
    uint32_t retransmitted, rejected_seen;
    uint16_t wake_free;
    /* a hook that may change a record's words as it is written (tests of the reject path) */
    void (*corrupt)(uint32_t seq, uint16_t *words, size_t n, void *ctx);
    void *corrupt_ctx;
} cnct_stream;

void cnct_stream_init(cnct_stream *s, cnct_card *card, uint32_t chunk_bytes, uint32_t lookahead_periods);
int cnct_stream_add(cnct_stream *s, const cnct_record *r);   /* frees nothing: free r yourself */
/* One exchange: take the bus, write what may go, give it back with ALL_SENT and WAKE_FREE. */
int cnct_stream_exchange(cnct_stream *s, const cnct_status *status);
/* Answer every status until the run is over: 0, or -1 (errno EPIPE) if the card's side went away.
 * on_status(status, ctx), if given, is called with each status first (add records there). */
int cnct_stream_run(cnct_stream *s, void (*on_status)(const cnct_status *, void *), void *ctx);
void cnct_stream_free(cnct_stream *s);

#endif
