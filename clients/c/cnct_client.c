/* cnct_client.c: the PC side of the cnc-twin card (see cnct_client.h). */
#define _GNU_SOURCE
#include "cnct_client.h"

#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <sched.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#define WAKE_INTERVAL_MS 2 /* the longest a waiting PC sleeps before its heartbeat and a look */

/* --- the whiteboard --------------------------------------------------------------------------- */

static uint32_t load32(const cnct_card *c, uint32_t word) {
    return __atomic_load_n((const volatile uint32_t *)(c->word + word), __ATOMIC_ACQUIRE);
}

static void store32(cnct_card *c, uint32_t word, uint32_t value) {
    __atomic_store_n((volatile uint32_t *)(c->word + word), value, __ATOMIC_RELEASE);
}

static uint16_t load16(const cnct_card *c, uint32_t word) {
    return __atomic_load_n(c->word + word, __ATOMIC_ACQUIRE);
}

static void store16(cnct_card *c, uint32_t word, uint16_t value) {
    __atomic_store_n(c->word + word, value, __ATOMIC_RELEASE);
}

static double now_s(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static char *joined(const char *folder, const char *name) {
    size_t n = strlen(folder) + strlen(name) + 2;
    char *path = malloc(n);
    if (path != NULL) snprintf(path, n, "%s/%s", folder, name);
    return path;
}

int cnct_open(cnct_card *card, const char *folder, double timeout_s) {
    struct sigaction pipe_action;
    /* a ring after the twin's process ended would raise SIGPIPE: that is an EPIPE return here */
    if (sigaction(SIGPIPE, NULL, &pipe_action) == 0 && pipe_action.sa_handler == SIG_DFL) signal(SIGPIPE, SIG_IGN);
    char *board = joined(folder, "whiteboard"), *to_pc = joined(folder, "to_pc"), *to_dsp = joined(folder, "to_dsp");
    int fd = -1, rc = -1;
    struct stat info;
    memset(card, 0, sizeof *card);
    card->wake_fd = card->ring_fd = -1;
    if (board == NULL || to_pc == NULL || to_dsp == NULL) goto done;
    double deadline = now_s() + timeout_s;
    while (access(to_pc, F_OK) != 0) { /* made last: the folder is whole once it is there */
        if (now_s() > deadline) { errno = ENOENT; goto done; }
        usleep(50000);
    }
    fd = open(board, O_RDWR | O_CLOEXEC);
    if (fd < 0 || fstat(fd, &info) != 0) goto done;
    void *memory = mmap(NULL, (size_t)info.st_size, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
    if (memory == MAP_FAILED) goto done;
    card->word = memory;
    card->words = (size_t)info.st_size / 2;
    card->wake_fd = open(to_pc, O_RDONLY | O_NONBLOCK | O_CLOEXEC);
    card->ring_fd = open(to_dsp, O_WRONLY | O_NONBLOCK | O_CLOEXEC);
    if (card->wake_fd < 0 || card->ring_fd < 0) goto done;
    rc = 0;
done:
    if (fd >= 0) close(fd);
    if (rc != 0 && card->word != NULL) {
        int saved = errno;
        cnct_close(card);
        errno = saved;
    }
    free(board);
    free(to_pc);
    free(to_dsp);
    return rc;
}

void cnct_close(cnct_card *card) {
    if (card->wake_fd >= 0) close(card->wake_fd);
    if (card->ring_fd >= 0) close(card->ring_fd);
    if (card->word != NULL) munmap((void *)card->word, card->words * 2);
    card->word = NULL;
    card->wake_fd = card->ring_fd = -1;
}

void cnct_attach(cnct_card *card, uint32_t program_periods) {
    store32(card, CNCT_PC_PROGRAM_PERIODS, program_periods);
    store16(card, CNCT_PC_VERSION, CNCT_VERSION);
    store32(card, CNCT_PC_MAGIC, CNCT_MAGIC);
    store16(card, CNCT_PC_STATE, CNCT_PC_STATE_READY);
}

static void beat(cnct_card *card) {
    store32(card, CNCT_PC_HEARTBEAT, load32(card, CNCT_PC_HEARTBEAT) + 1u);
}

int cnct_wait_status(cnct_card *card, cnct_status *out) {
    uint32_t mailbox = CNCT_MAILBOX_TO_PC(card->words), shutdown = CNCT_DSP_CONTROL(card->words) + CNCT_DSP_SHUTDOWN;
    struct pollfd bell = {card->wake_fd, POLLIN, 0};
    char drain[256];
    for (unsigned i = 0; i < card->spin_polls && load16(card, mailbox) == card->last_seen; i++) {}
    while (load16(card, mailbox) == card->last_seen && !load16(card, shutdown)) {
        beat(card);
        if (poll(&bell, 1, WAKE_INTERVAL_MS) > 0) {
            if (bell.revents & POLLIN) {
                while (read(card->wake_fd, drain, sizeof drain) > 0) {}
            } else if (bell.revents & POLLHUP) { /* no writer left: the twin's process ended */
                errno = EPIPE;
                return -1;
            }
        }
    }
    if (load16(card, shutdown)) return 0;
    card->last_seen = load16(card, mailbox);
    beat(card);
    memcpy(out, (const void *)(card->word + CNCT_STATUS_BASE(card->words)), sizeof *out);
    return 1;
}

int cnct_end_state(const cnct_card *card, uint16_t *state, uint16_t *fault) {
    uint32_t dsp = CNCT_DSP_CONTROL(card->words);
    if (!load16(card, dsp + CNCT_DSP_SHUTDOWN)) return -1;
    *state = load16(card, dsp + CNCT_DSP_END_STATE);
    *fault = load16(card, dsp + CNCT_DSP_END_FAULT);
    return 0;
}

void cnct_begin(cnct_card *card) {
    store16(card, CNCT_PC_HOLD, 1);
    while (!load16(card, CNCT_DSP_CONTROL(card->words) + CNCT_DSP_HOLDA)) sched_yield();
}

void cnct_end(cnct_card *card, int all_sent, uint16_t wake_free) {
    struct timespec t;
    store16(card, CNCT_PC_ALL_SENT, all_sent ? 1 : 0);
    store16(card, CNCT_PC_WAKE_FREE, wake_free);
    store16(card, CNCT_PC_HOLD, 0);
    clock_gettime(CLOCK_MONOTONIC, &t);
    __atomic_store_n((volatile uint64_t *)(card->word + CNCT_PC_ACK_TIME),
                     (uint64_t)t.tv_sec * 1000000000u + (uint64_t)t.tv_nsec, __ATOMIC_RELEASE);
    store16(card, CNCT_MAILBOX_TO_DSP(card->words), card->last_seen);
    if (write(card->ring_fd, "\1", 1) < 0) { /* a full pipe: the card has wake-ups pending */ }
}

uint32_t cnct_fifo_free(const cnct_card *card) {
    uint32_t written = load32(card, CNCT_PC_FIFO_WRITE);
    uint32_t read_ = load32(card, CNCT_DSP_CONTROL(card->words) + CNCT_DSP_FIFO_READ);
    return CNCT_FIFO_WORDS(card->words) - (written - read_);
}

void cnct_fifo_write(cnct_card *card, const uint16_t *words, size_t n) {
    uint32_t base = CNCT_FIFO_BASE(card->words), capacity = CNCT_FIFO_WORDS(card->words);
    uint32_t index = load32(card, CNCT_PC_FIFO_WRITE);
    for (size_t i = 0; i < n; i++) card->word[base + (uint32_t)((index + i) % capacity)] = words[i];
    store32(card, CNCT_PC_FIFO_WRITE, index + (uint32_t)n); /* published after the data */
}

/* --- records ---------------------------------------------------------------------------------- */

static int make(cnct_record *r, uint16_t type, const void *payload, size_t bytes, uint32_t periods) {
    r->type = type;
    r->in_parts = 0;
    r->periods = periods;
    r->words = bytes / 2;
    r->payload = malloc(bytes ? bytes : 2);
    if (r->payload == NULL) return -1;
    if (bytes) memcpy(r->payload, payload, bytes);
    return 0;
}

int cnct_move(cnct_record *r, const double end[6], double t_acc, double t_flat, double v_peak, double accel,
              uint32_t periods) {
    cnct_move_payload p;
    memcpy(p.end, end, sizeof p.end);
    p.t_acc = t_acc; p.t_flat = t_flat; p.v_peak = v_peak; p.accel = accel; p.periods = periods;
    return make(r, CNCT_TYPE_MOVE, &p, sizeof p, periods);
}

int cnct_dwell(cnct_record *r, uint32_t periods) {
    cnct_dwell_payload p = {periods};
    return make(r, CNCT_TYPE_DWELL, &p, sizeof p, periods);
}

int cnct_feed_override(cnct_record *r, double fraction) {
    cnct_fraction_payload p = {fraction};
    return make(r, CNCT_TYPE_FEED_OVERRIDE, &p, sizeof p, 0);
}

int cnct_force_setpoint(cnct_record *r, double newtons) {
    cnct_newtons_payload p = {newtons};
    return make(r, CNCT_TYPE_FORCE_SETPOINT, &p, sizeof p, 0);
}

int cnct_spindle(cnct_record *r, int on, double speed) {
    cnct_spindle_payload p = {on ? 1 : 0, 0, speed};
    return make(r, CNCT_TYPE_SPINDLE, &p, sizeof p, 0);
}

int cnct_mark(cnct_record *r, uint32_t number) {
    cnct_mark_payload p = {number};
    return make(r, CNCT_TYPE_MARK, &p, sizeof p, 0);
}

int cnct_end_of_program(cnct_record *r) {
    return make(r, CNCT_TYPE_END_OF_PROGRAM, NULL, 0, 0);
}

int cnct_curve_geometry(cnct_record *r, uint16_t degree, uint16_t n, const double *knots, const double *weights,
                        const double *points, const double held[3]) {
    size_t nk = (size_t)n + degree + 1, values = nk + n + 3 * (size_t)n;
    size_t bytes = sizeof(cnct_curve_head_payload) + 8 * values;
    if (bytes / 2 > CNCT_MAX_GEOMETRY_WORDS) { errno = EMSGSIZE; return -1; }
    uint8_t *buffer = malloc(bytes);
    if (buffer == NULL) return -1;
    cnct_curve_head_payload head = {degree, n, 0, 0, {held[0], held[1], held[2]}};
    memcpy(buffer, &head, sizeof head);
    uint8_t *at = buffer + sizeof head;
    memcpy(at, knots, 8 * nk);
    memcpy(at + 8 * nk, weights, 8 * (size_t)n);
    memcpy(at + 8 * (nk + n), points, 24 * (size_t)n);
    int rc = make(r, CNCT_TYPE_CURVE_GEOMETRY, buffer, bytes, 0);
    r->in_parts = 1;
    free(buffer);
    return rc;
}

int cnct_curve_block(cnct_record *r, double length, double v0, double vp, double v1, double a_max, double j_max,
                     uint32_t periods) {
    cnct_curve_block_payload p = {length, v0, vp, v1, a_max, j_max};
    return make(r, CNCT_TYPE_CURVE_BLOCK, &p, sizeof p, periods);
}

void cnct_record_free(cnct_record *r) {
    free(r->payload);
    r->payload = NULL;
}

uint16_t cnct_crc16(const uint8_t *data, size_t n) {
    uint16_t crc = 0xFFFF;
    for (size_t i = 0; i < n; i++) {
        crc ^= (uint16_t)(data[i] << 8);
        for (int bit = 0; bit < 8; bit++) crc = (crc & 0x8000) ? (uint16_t)((crc << 1) ^ 0x1021) : (uint16_t)(crc << 1);
    }
    return crc;
}

/* --- streaming -------------------------------------------------------------------------------- */

void cnct_stream_init(cnct_stream *s, cnct_card *card, uint32_t chunk_bytes, uint32_t lookahead_periods) {
    memset(s, 0, sizeof *s);
    s->card = card;
    s->chunk_words = chunk_bytes / 2;
    s->lookahead_periods = lookahead_periods;
    s->fifo_interrupt = 1;
}

static int push(cnct_stream *s, uint16_t type, const void *head, size_t head_words, const uint16_t *payload,
                size_t words, uint32_t periods) {
    if (s->count + 1 >= s->capacity) {
        size_t capacity = s->capacity ? 2 * s->capacity : 64;
        uint16_t **encoded = realloc(s->encoded, capacity * sizeof *encoded);
        if (encoded == NULL) return -1;
        s->encoded = encoded;
        size_t *lengths = realloc(s->lengths, capacity * sizeof *lengths);
        if (lengths == NULL) return -1;
        s->lengths = lengths;
        uint64_t *cumulative = realloc(s->cumulative, (capacity + 1) * sizeof *cumulative);
        if (cumulative == NULL) return -1;
        s->cumulative = cumulative;
        if (s->capacity == 0) s->cumulative[0] = 0;
        s->capacity = capacity;
    }
    size_t n = head_words + words, total = CNCT_HEADER_WORDS + n + CNCT_TRAILER_WORDS;
    uint16_t *w = malloc(total * 2);
    if (w == NULL) return -1;
    uint32_t seq = (uint32_t)s->count + 1;
    w[0] = (uint16_t)(CNCT_SYNC << 8 | type);
    w[1] = (uint16_t)n;
    w[2] = (uint16_t)~n;
    w[3] = (uint16_t)(seq & 0xFFFF);
    w[4] = (uint16_t)(seq >> 16);
    if (head_words) memcpy(w + CNCT_HEADER_WORDS, head, head_words * 2);
    if (words) memcpy(w + CNCT_HEADER_WORDS + head_words, payload, words * 2);
    w[total - 1] = cnct_crc16((const uint8_t *)w, (total - 1) * 2);
    s->encoded[s->count] = w;
    s->lengths[s->count] = total;
    s->cumulative[s->count + 1] = s->cumulative[s->count] + periods;
    s->count++;
    return 0;
}

int cnct_stream_add(cnct_stream *s, const cnct_record *r) {
    size_t limit = s->chunk_words < CNCT_HEADER_WORDS + CNCT_TRAILER_WORDS + CNCT_MAX_PAYLOAD_WORDS
                       ? s->chunk_words : CNCT_HEADER_WORDS + CNCT_TRAILER_WORDS + CNCT_MAX_PAYLOAD_WORDS;
    size_t capacity = limit - CNCT_HEADER_WORDS - CNCT_TRAILER_WORDS;
    if (!r->in_parts || r->words <= capacity) return push(s, r->type, NULL, 0, r->payload, r->words, r->periods);
    size_t piece = capacity - CNCT_PART_HEAD_WORDS, count = (r->words + piece - 1) / piece;
    for (size_t i = 0; i < count; i++) {
        size_t words = i + 1 < count ? piece : r->words - i * piece;
        cnct_part_head_payload head = {r->type, (uint16_t)i, (uint16_t)count, 0};
        if (push(s, CNCT_TYPE_GEOMETRY_PART, &head, CNCT_PART_HEAD_WORDS, r->payload + i * piece, words,
                 i + 1 == count ? r->periods : 0) != 0)
            return -1;
    }
    return 0;
}

static int answer(cnct_stream *s, const cnct_status *st) {
    if (st->records_rejected != s->rejected_seen) { /* go back to what the card expects */
        s->rejected_seen = st->records_rejected;
        size_t from = st->expected_seq - 1;
        if (s->next_index > from) s->retransmitted += (uint32_t)(s->next_index - from);
        s->next_index = from;
    }
    size_t accepted = st->expected_seq - 1, executed = st->last_seq_executed;
    uint32_t budget = s->chunk_words, free_words = cnct_fifo_free(s->card);
    int written = 0;
    s->wake_free = 0;
    while (s->next_index < s->count) {
        uint64_t queued = st->queued_periods + s->cumulative[s->next_index] - s->cumulative[accepted];
        if (s->lookahead_periods && queued >= s->lookahead_periods && s->next_index > executed + 1
            && st->state != CNCT_DSP_STATE_FEED_HOLD)
            break;
        size_t n = s->lengths[s->next_index];
        if (n > free_words) { /* the FIFO must drain first */
            s->wake_free = (uint16_t)n;
            break;
        }
        if (n > budget && written) break; /* a record longer than the chunk goes alone */
        uint16_t *words = s->encoded[s->next_index];
        if (s->corrupt != NULL) {
            uint16_t *copy = malloc(n * 2);
            if (copy == NULL) return -1;
            memcpy(copy, words, n * 2);
            s->corrupt((uint32_t)s->next_index + 1, copy, n, s->corrupt_ctx);
            cnct_fifo_write(s->card, copy, n);
            free(copy);
        } else {
            cnct_fifo_write(s->card, words, n);
        }
        budget -= (uint32_t)(n < budget ? n : budget);
        free_words -= (uint32_t)n;
        s->next_index++;
        written++;
    }
    return written;
}

int cnct_stream_exchange(cnct_stream *s, const cnct_status *status) {
    cnct_begin(s->card);
    int written = answer(s, status);
    store32(s->card, CNCT_PC_RECORDS_SENT, (uint32_t)s->next_index);
    store32(s->card, CNCT_PC_RETRANSMITS, s->retransmitted);
    int all_sent = s->complete && s->next_index >= s->count;
    cnct_end(s->card, all_sent, s->fifo_interrupt ? s->wake_free : 0);
    store16(s->card, CNCT_PC_STATE, CNCT_PC_STATE_STREAMING);
    return written;
}

int cnct_stream_run(cnct_stream *s, void (*on_status)(const cnct_status *, void *), void *ctx) {
    cnct_status status;
    int got;
    while ((got = cnct_wait_status(s->card, &status)) == 1) {
        if (on_status != NULL) on_status(&status, ctx);
        if (cnct_stream_exchange(s, &status) < 0) return -1;
    }
    store16(s->card, CNCT_PC_STATE, CNCT_PC_STATE_DONE);
    return got;
}

void cnct_stream_free(cnct_stream *s) {
    for (size_t i = 0; i < s->count; i++) free(s->encoded[i]);
    free(s->encoded);
    free(s->lengths);
    free(s->cumulative);
    memset(s, 0, sizeof *s);
}
