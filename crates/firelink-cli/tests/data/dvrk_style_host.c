/* A host that uses libraw1394 the way the dVRK's FirewirePort does (its
 * calls, in its order; written for Firelink's tests, not copied): a
 * handle, the port list, the port, a bus reset handler that records the
 * generation, the generation checks, STATE_CLEAR to stop cycle start,
 * quadlet and block reads and quadlet writes to every board, then the fd
 * and loop_iterate to pick up events. Prints one line per board:
 *   node <n> hw <hex> fw <hex> wd <hex> block <hex>,<hex>   (hex: 8 digits)
 * Exit status 0 when every call worked. */
#include <arpa/inet.h>
#include <errno.h>
#include <libraw1394/raw1394.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/select.h>

static unsigned int generation_seen;

static int on_bus_reset(raw1394handle_t h, unsigned int generation)
{
    generation_seen = generation;
    raw1394_update_generation(h, generation);
    return 0;
}

static int fail(const char *what)
{
    fprintf(stderr, "%s: %s\n", what, strerror(errno));
    return 1;
}

int main(void)
{
    raw1394handle_t h = raw1394_new_handle();
    if (!h)
        return fail("raw1394_new_handle");
    struct raw1394_portinfo ports[4];
    int nports = raw1394_get_port_info(h, ports, 4);
    if (nports < 1)
        return fail("raw1394_get_port_info");
    if (raw1394_set_port(h, 0) != 0)
        return fail("raw1394_set_port");
    raw1394_set_bus_reset_handler(h, on_bus_reset);
    printf("libversion %s\n", raw1394_get_libversion());
    nodeid_t local = raw1394_get_local_id(h);
    int nodes = raw1394_get_nodecount(h);
    unsigned int generation = raw1394_get_generation(h);
    printf("nodes %d local %d generation %u\n", nodes, local & 0x3f, generation);

    /* Stop cycle start packets: STATE_CLEAR bit 8 of the local node. */
    quadlet_t cmstr = htonl(0x100);
    if (raw1394_write(h, local, 0xfffff0000000ULL, 4, &cmstr) != 0)
        return fail("STATE_CLEAR");

    /* The PC is the highest node: boards are 0 .. nodes - 2. */
    for (int node = 0; node < nodes - 1; node++) {
        nodeid_t id = 0xffc0 | node;
        if (raw1394_get_generation(h) != generation)
            return fail("generation changed");
        quadlet_t hw, fw, wd, block[2];
        if (raw1394_read(h, id, 4, 4, &hw) != 0)
            return fail("read HARDWARE_VERSION");
        if (raw1394_read(h, id, 7, 4, &fw) != 0)
            return fail("read FIRMWARE_VERSION");
        quadlet_t period = htonl(0x1680 + node);
        if (raw1394_write(h, id, 3, 4, &period) != 0)
            return fail("write WATCHDOG");
        if (raw1394_read(h, id, 3, 4, &wd) != 0)
            return fail("read WATCHDOG");
        if (raw1394_read(h, id, 4, 8, block) != 0)
            return fail("block read");
        printf("node %d hw %08x fw %08x wd %08x block %08x,%08x\n", node, ntohl(hw),
               ntohl(fw), ntohl(wd), ntohl(block[0]), ntohl(block[1]));
    }

    /* What the dVRK does between cycles: a zero-timeout select on the fd,
     * loop_iterate when it is readable. Nothing is queued now: one echo
     * request makes loop_iterate return at once. */
    int fd = raw1394_get_fd(h);
    fd_set set;
    FD_ZERO(&set);
    FD_SET(fd, &set);
    struct timeval zero = {0, 0};
    if (select(fd + 1, &set, NULL, NULL, &zero) < 0)
        return fail("select");
    /* (Its return value is the bytes it wrote on libraw1394 2.1's firewire
     * backend, not 0: only loop_iterate's answer tells.) */
    raw1394_echo_request(h, 0x1394);
    if (raw1394_loop_iterate(h) != 0x1394)
        return fail("raw1394_loop_iterate");
    raw1394_destroy_handle(h);
    printf("done\n");
    return 0;
}
