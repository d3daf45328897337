/*
 * insn_probe: exact guest instruction counts between probe points, a QEMU TCG plugin.
 *
 * The guest marks points in its program by calling into a table of `bx lr` instructions
 * (`aim_probe_table`, one 2-byte slot per probe id; see m4f/src/probe.rs). Each slot is a
 * translation block of its own, so the plugin sees exactly which probe ran. Every executed
 * translation block adds its instruction count to one counter (an inline add, no callback);
 * a probe hit charges the instructions since the previous hit to the previous probe's id.
 * Probe id `dump` writes the totals per id to the output file and starts a new section.
 *
 * Arguments: base=<address of aim_probe_table>, slots=<number of ids>, dump=<id>,
 *            out=<file to write>.
 * Output lines: `section <n>` then `probe <id> <instructions> <entries>` per id entered.
 *
 * QEMU's installed packages ship no plugin header, so the few functions of the stable plugin
 * API (QEMU_PLUGIN_VERSION 1, QEMU 7.x) used here are declared below, as in qemu-plugin.h.
 */
#include <inttypes.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef uint64_t qemu_plugin_id_t;
struct qemu_plugin_tb;
enum qemu_plugin_cb_flags { QEMU_PLUGIN_CB_NO_REGS, QEMU_PLUGIN_CB_R_REGS, QEMU_PLUGIN_CB_RW_REGS };
enum qemu_plugin_op { QEMU_PLUGIN_INLINE_ADD_U64 };
typedef void (*qemu_plugin_vcpu_tb_trans_cb_t)(qemu_plugin_id_t id, struct qemu_plugin_tb *tb);
typedef void (*qemu_plugin_vcpu_udata_cb_t)(unsigned int vcpu_index, void *userdata);
typedef void (*qemu_plugin_udata_cb_t)(qemu_plugin_id_t id, void *userdata);
void qemu_plugin_register_vcpu_tb_trans_cb(qemu_plugin_id_t id, qemu_plugin_vcpu_tb_trans_cb_t cb);
void qemu_plugin_register_vcpu_tb_exec_cb(struct qemu_plugin_tb *tb, qemu_plugin_vcpu_udata_cb_t cb,
                                          enum qemu_plugin_cb_flags flags, void *userdata);
void qemu_plugin_register_vcpu_tb_exec_inline(struct qemu_plugin_tb *tb, enum qemu_plugin_op op,
                                              void *ptr, uint64_t imm);
void qemu_plugin_register_atexit_cb(qemu_plugin_id_t id, qemu_plugin_udata_cb_t cb, void *userdata);
size_t qemu_plugin_tb_n_insns(const struct qemu_plugin_tb *tb);
uint64_t qemu_plugin_tb_vaddr(const struct qemu_plugin_tb *tb);

__attribute__((visibility("default"))) int qemu_plugin_version = 1;

#define MAX_SLOTS 256

static uint64_t insns;       /* instructions executed so far (single vCPU) */
static uint64_t base;        /* address of slot 0 */
static unsigned slots;       /* number of probe ids */
static unsigned dump_id;     /* the id that writes a section */
static FILE *out;
static unsigned current;     /* id of the last probe hit; 0 before the first */
static uint64_t last;        /* `insns` at the last probe hit */
static uint64_t total[MAX_SLOTS];
static uint64_t entries[MAX_SLOTS];
static unsigned section;

static void write_section(void)
{
    section++;
    fprintf(out, "section %u\n", section);
    for (unsigned i = 0; i < slots; i++) {
        if (entries[i] != 0) {
            fprintf(out, "probe %u %" PRIu64 " %" PRIu64 "\n", i, total[i], entries[i]);
        }
        total[i] = 0;
        entries[i] = 0;
    }
    fflush(out);
}

static void probe_hit(unsigned int vcpu, void *udata)
{
    unsigned id = (unsigned)(uintptr_t)udata;
    (void)vcpu;
    total[current] += insns - last;
    last = insns;
    current = id;
    entries[id]++;
    if (id == dump_id) {
        write_section();
    }
}

static void tb_trans(qemu_plugin_id_t id, struct qemu_plugin_tb *tb)
{
    uint64_t pc = qemu_plugin_tb_vaddr(tb);
    (void)id;
    if (pc >= base && pc < base + 2 * (uint64_t)slots && (pc - base) % 2 == 0) {
        qemu_plugin_register_vcpu_tb_exec_cb(tb, probe_hit, QEMU_PLUGIN_CB_NO_REGS,
                                             (void *)(uintptr_t)((pc - base) / 2));
    }
    qemu_plugin_register_vcpu_tb_exec_inline(tb, QEMU_PLUGIN_INLINE_ADD_U64, &insns,
                                             qemu_plugin_tb_n_insns(tb));
}

static void at_exit(qemu_plugin_id_t id, void *udata)
{
    (void)id;
    (void)udata;
    fprintf(out, "exit %" PRIu64 "\n", insns);
    fclose(out);
}

__attribute__((visibility("default"))) int qemu_plugin_install(qemu_plugin_id_t id,
                                                               const void *info, int argc,
                                                               char **argv)
{
    const char *path = NULL;
    (void)info;
    for (int i = 0; i < argc; i++) {
        if (strncmp(argv[i], "base=", 5) == 0) {
            base = strtoull(argv[i] + 5, NULL, 0);
        } else if (strncmp(argv[i], "slots=", 6) == 0) {
            slots = (unsigned)strtoul(argv[i] + 6, NULL, 0);
        } else if (strncmp(argv[i], "dump=", 5) == 0) {
            dump_id = (unsigned)strtoul(argv[i] + 5, NULL, 0);
        } else if (strncmp(argv[i], "out=", 4) == 0) {
            path = argv[i] + 4;
        } else {
            fprintf(stderr, "insn_probe: unknown argument `%s`\n", argv[i]);
            return -1;
        }
    }
    if (base == 0 || slots == 0 || slots > MAX_SLOTS || dump_id >= slots || path == NULL) {
        fprintf(stderr, "insn_probe: need base=ADDR slots=1..%d dump=ID<slots out=FILE\n",
                MAX_SLOTS);
        return -1;
    }
    out = fopen(path, "w");
    if (out == NULL) {
        fprintf(stderr, "insn_probe: cannot create `%s`\n", path);
        return -1;
    }
    qemu_plugin_register_vcpu_tb_trans_cb(id, tb_trans);
    qemu_plugin_register_atexit_cb(id, at_exit, NULL);
    return 0;
}
