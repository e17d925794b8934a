/* pc_echo.c: the PC side of the external round-trip benchmark, in C (clients/c): attach, then
 * acknowledge every status, writing nothing, until the run is over.
 *     pc_echo [SPIN_POLLS] ATTACH_FOLDER */
#include <stdio.h>
#include <stdlib.h>

#include "cnct_client.h"

int main(int argc, char **argv) {
    cnct_card card;
    cnct_status status;
    if (argc < 2 || cnct_open(&card, argv[argc - 1], 30.0) != 0) {
        perror(argc < 2 ? "usage: pc_echo [SPIN_POLLS] ATTACH_FOLDER" : argv[argc - 1]);
        return 1;
    }
    card.spin_polls = argc > 2 ? (unsigned)atoi(argv[1]) : 0;
    cnct_attach(&card, 0);
    while (cnct_wait_status(&card, &status) == 1) {
        cnct_begin(&card);
        cnct_end(&card, 0, 0);
    }
    cnct_close(&card);
    return 0;
}
