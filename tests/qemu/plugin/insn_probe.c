/*
 * insn_probe: exact guest instruction counts, charged to ids, a QEMU TCG plugin.
 *
 * A map file assigns ids to guest address ranges (`<start> <end> <id>` per line, hex or
 * decimal, end exclusive). Every executed translation block adds its instruction count to one
 * counter (an inline add, no callback). A translation block whose first address lies in a mapped
 * range switches the current id when it runs: the instructions since the last switch are
 * charged to the previous id. Blocks outside every range leave the id as it is, so shared code
 * (an FFT, libm) is charged to whoever called it.
 *
 * Two kinds of ranges are mapped (see xtask/src/instructions.rs): the guest's probe table, a
 * table of `bx lr` instructions, one 2-byte slot per probe id, which the guest calls to mark a
 * point explicitly (m4f/src/lib.rs); and the code of each DSP stage, found from the ELF's debug
 * information (inlined functions included).
 *
 * Id `dump` writes the totals per id to the output file and starts a new section.
 *
 * Arguments: map=<file>, ids=<number of ids>, dump=<id>, out=<file to write>.
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

#define MAX_IDS 256
#define MAX_RANGES 65536

struct range {
    uint64_t start, end;
    unsigned id;
};

static uint64_t insns;       /* instructions executed so far (single vCPU) */
static struct range ranges[MAX_RANGES];
static size_t range_count;   /* sorted by start, not overlapping */
static unsigned ids;         /* number of ids */
static unsigned dump_id;     /* the id that writes a section */
static FILE *out;
static unsigned current;     /* id in force; 0 before the first switch */
static uint64_t last;        /* `insns` at the last switch */
static uint64_t total[MAX_IDS];
static uint64_t entries[MAX_IDS];
static unsigned section;

static void write_section(void)
{
    section++;
    fprintf(out, "section %u\n", section);
    for (unsigned i = 0; i < ids; i++) {
        if (entries[i] != 0) {
            fprintf(out, "probe %u %" PRIu64 " %" PRIu64 "\n", i, total[i], entries[i]);
        }
        total[i] = 0;
        entries[i] = 0;
    }
    fflush(out);
}

static void switch_id(unsigned int vcpu, void *udata)
{
    unsigned id = (unsigned)(uintptr_t)udata;
    (void)vcpu;
    if (id == current) {
        return;
    }
    total[current] += insns - last;
    last = insns;
    current = id;
    entries[id]++;
    if (id == dump_id) {
        write_section();
    }
}

/* The id of the range holding `pc`, or -1. */
static int lookup(uint64_t pc)
{
    size_t lo = 0, hi = range_count;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (pc < ranges[mid].start) {
            hi = mid;
        } else if (pc >= ranges[mid].end) {
            lo = mid + 1;
        } else {
            return (int)ranges[mid].id;
        }
    }
    return -1;
}

static void tb_trans(qemu_plugin_id_t id, struct qemu_plugin_tb *tb)
{
    int mapped = lookup(qemu_plugin_tb_vaddr(tb));
    (void)id;
    if (mapped >= 0) {
        qemu_plugin_register_vcpu_tb_exec_cb(tb, switch_id, QEMU_PLUGIN_CB_NO_REGS,
                                             (void *)(uintptr_t)mapped);
    }
    qemu_plugin_register_vcpu_tb_exec_inline(tb, QEMU_PLUGIN_INLINE_ADD_U64, &insns,
                                             qemu_plugin_tb_n_insns(tb));
}

static int by_start(const void *a, const void *b)
{
    const struct range *x = a, *y = b;
    return x->start < y->start ? -1 : x->start > y->start;
}

/* Reads the map; 0 on success. */
static int read_map(const char *path)
{
    FILE *f = fopen(path, "r");
    unsigned long long start, end;
    unsigned id;
    if (f == NULL) {
        fprintf(stderr, "insn_probe: cannot open map `%s`\n", path);
        return -1;
    }
    while (fscanf(f, "%lli %lli %u", &start, &end, &id) == 3) {
        if (range_count == MAX_RANGES || id >= ids || end <= start) {
            fprintf(stderr, "insn_probe: bad or too many ranges in `%s`\n", path);
            fclose(f);
            return -1;
        }
        ranges[range_count++] = (struct range){ start, end, id };
    }
    if (!feof(f)) {
        fprintf(stderr, "insn_probe: cannot read line %zu of `%s`\n", range_count + 1, path);
        fclose(f);
        return -1;
    }
    fclose(f);
    qsort(ranges, range_count, sizeof ranges[0], by_start);
    for (size_t i = 1; i < range_count; i++) {
        if (ranges[i].start < ranges[i - 1].end) {
            fprintf(stderr, "insn_probe: overlapping ranges in `%s`\n", path);
            return -1;
        }
    }
    return 0;
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
    const char *path = NULL, *map = NULL;
    (void)info;
    for (int i = 0; i < argc; i++) {
        if (strncmp(argv[i], "map=", 4) == 0) {
            map = argv[i] + 4;
        } else if (strncmp(argv[i], "ids=", 4) == 0) {
            ids = (unsigned)strtoul(argv[i] + 4, NULL, 0);
        } else if (strncmp(argv[i], "dump=", 5) == 0) {
            dump_id = (unsigned)strtoul(argv[i] + 5, NULL, 0);
        } else if (strncmp(argv[i], "out=", 4) == 0) {
            path = argv[i] + 4;
        } else {
            fprintf(stderr, "insn_probe: unknown argument `%s`\n", argv[i]);
            return -1;
        }
    }
    if (map == NULL || ids == 0 || ids > MAX_IDS || dump_id >= ids || path == NULL) {
        fprintf(stderr, "insn_probe: need map=FILE ids=1..%d dump=ID<ids out=FILE\n", MAX_IDS);
        return -1;
    }
    if (read_map(map) != 0) {
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
