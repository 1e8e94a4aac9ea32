/*
 * The least a UDP router can do, as a floor for benches/scripts/router_compare.sh:
 * block in recv() on 127.0.0.1:IN_PORT and send each datagram as it is to
 * 127.0.0.1:OUT_PORT. No parsing, no routing table, no event loop: two
 * system calls per datagram. What a router costs above this is its own
 * work; what this costs is the kernel's (waking the process, and the
 * receiver on the far end of each send).
 *
 *   udp_forward IN_PORT OUT_PORT
 */
#include <netinet/in.h>
#include <stdio.h>
#include <stdlib.h>
#include <sys/socket.h>

static int udp_socket(int port, int bind_it) {
    int fd = socket(AF_INET, SOCK_DGRAM, 0);
    struct sockaddr_in a = {.sin_family = AF_INET, .sin_port = htons((uint16_t)port),
                            .sin_addr.s_addr = htonl(INADDR_LOOPBACK)};
    if (fd < 0 || (bind_it ? bind(fd, (struct sockaddr *)&a, sizeof a)
                           : connect(fd, (struct sockaddr *)&a, sizeof a)) != 0) {
        perror("udp_forward: socket");
        exit(1);
    }
    return fd;
}

int main(int argc, char **argv) {
    if (argc != 3) {
        fprintf(stderr, "usage: %s IN_PORT OUT_PORT\n", argv[0]);
        return 2;
    }
    int in = udp_socket(atoi(argv[1]), 1), out = udp_socket(atoi(argv[2]), 0);
    static char buf[65536];
    for (;;) {
        ssize_t n = recv(in, buf, sizeof buf, 0);
        if (n > 0) send(out, buf, (size_t)n, 0); /* a full buffer drops, as a router would */
    }
}
