/* QEMU TCG plugin (plugin API v1, QEMU 7.2 as in Debian 12): counts guest instructions exactly as
 * ../shared/tools/qemu-insncount/insn_count.c does (each translation block adds its number of
 * instructions when it starts), and in addition writes the running count, one decimal line each,
 * every time the guest executes the instruction at address MARK. The firmware's `replay-all` mode
 * calls such a mark function between the pieces it measures, so that one run yields what two
 * whole runs per piece gave before (scripts/measure-firmware).
 *
 * Build: gcc -shared -fPIC -O2 -o libinsnmarks.so insn_marks.c
 * Use:   qemu-system-arm ... -icount shift=0 -plugin ./libinsnmarks.so,mark=0xADDR[,per-insn=on]
 * (per-insn=on: counted instruction by instruction, as insn_count.c's option; the same counts).
 * Writes "insns: N" (the total) and then the marks to $INSN_MARKS_FILE (required), and
 * "insns: N" to stderr at exit.
 */
#include <stdint.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef uint64_t qemu_plugin_id_t;
typedef struct {
    const char *target_name;
    struct { int min; int cur; } version;
    bool system_emulation;
    union { struct { int smp_vcpus; int max_vcpus; } system; };
} qemu_info_t;
struct qemu_plugin_tb;
struct qemu_plugin_insn;
enum qemu_plugin_op { QEMU_PLUGIN_INLINE_ADD_U64 };
enum qemu_plugin_cb_flags { QEMU_PLUGIN_CB_NO_REGS, QEMU_PLUGIN_CB_R_REGS, QEMU_PLUGIN_CB_RW_REGS };
typedef void (*qemu_plugin_udata_cb_t)(qemu_plugin_id_t id, void *userdata);
typedef void (*qemu_plugin_vcpu_udata_cb_t)(unsigned int vcpu_index, void *userdata);
typedef void (*qemu_plugin_vcpu_tb_trans_cb_t)(qemu_plugin_id_t id, struct qemu_plugin_tb *tb);
extern void qemu_plugin_register_vcpu_tb_trans_cb(qemu_plugin_id_t id, qemu_plugin_vcpu_tb_trans_cb_t cb);
extern void qemu_plugin_register_vcpu_tb_exec_inline(struct qemu_plugin_tb *tb, enum qemu_plugin_op op, void *ptr, uint64_t imm);
extern void qemu_plugin_register_vcpu_insn_exec_inline(struct qemu_plugin_insn *insn, enum qemu_plugin_op op, void *ptr, uint64_t imm);
extern void qemu_plugin_register_vcpu_insn_exec_cb(struct qemu_plugin_insn *insn, qemu_plugin_vcpu_udata_cb_t cb, enum qemu_plugin_cb_flags flags, void *userdata);
extern uint64_t qemu_plugin_insn_vaddr(const struct qemu_plugin_insn *insn);
extern size_t qemu_plugin_tb_n_insns(const struct qemu_plugin_tb *tb);
extern struct qemu_plugin_insn *qemu_plugin_tb_get_insn(const struct qemu_plugin_tb *tb, size_t idx);
extern void qemu_plugin_register_atexit_cb(qemu_plugin_id_t id, qemu_plugin_udata_cb_t cb, void *userdata);

__attribute__((visibility("default"))) int qemu_plugin_version = 1;

static uint64_t insn_count;
static uint64_t mark;
static bool have_mark;
static bool per_insn;
static uint64_t *marks;
static size_t n_marks, cap_marks;
static bool failed;
static bool reported;

static void report(void) {
    if (reported) return;
    reported = true;
    fprintf(stderr, "insns: %llu\n", (unsigned long long)insn_count);
    const char *f = getenv("INSN_MARKS_FILE");
    FILE *o = f ? fopen(f, "w") : NULL;
    if (!o) { fputs("insn_marks: INSN_MARKS_FILE unset or not writable\n", stderr); return; }
    fprintf(o, "insns: %llu\n", (unsigned long long)insn_count);
    /* A mark that could not be stored leaves the file without its marks: the reader fails. */
    if (failed) fputs("error: out of memory for marks\n", o);
    else
        for (size_t i = 0; i < n_marks; i++) fprintf(o, "%llu\n", (unsigned long long)marks[i]);
    fclose(o);
}
static void on_exit_cb(qemu_plugin_id_t id, void *p) { (void)id; (void)p; report(); }
__attribute__((destructor)) static void on_unload(void) { report(); }

static void on_mark(unsigned int vcpu, void *p) {
    (void)vcpu; (void)p;
    if (failed) return;
    if (n_marks == cap_marks) {
        size_t cap = cap_marks ? 2 * cap_marks : 4096;
        uint64_t *m = realloc(marks, cap * sizeof *m);
        if (!m) { failed = true; return; }
        marks = m;
        cap_marks = cap;
    }
    marks[n_marks++] = insn_count;
}

static void tb_trans(qemu_plugin_id_t id, struct qemu_plugin_tb *tb) {
    (void)id;
    size_t n = qemu_plugin_tb_n_insns(tb);
    /* Counted as insn_count.c counts: the whole block when it starts. */
    if (!per_insn) qemu_plugin_register_vcpu_tb_exec_inline(tb, QEMU_PLUGIN_INLINE_ADD_U64, &insn_count, n);
    for (size_t i = 0; i < n; i++) {
        struct qemu_plugin_insn *insn = qemu_plugin_tb_get_insn(tb, i);
        if (per_insn) qemu_plugin_register_vcpu_insn_exec_inline(insn, QEMU_PLUGIN_INLINE_ADD_U64, &insn_count, 1);
        if (have_mark && qemu_plugin_insn_vaddr(insn) == mark)
            qemu_plugin_register_vcpu_insn_exec_cb(insn, on_mark, QEMU_PLUGIN_CB_NO_REGS, NULL);
    }
}

__attribute__((visibility("default")))
int qemu_plugin_install(qemu_plugin_id_t id, const qemu_info_t *info, int argc, char **argv) {
    (void)info;
    for (int i = 0; i < argc; i++)
        if (!strncmp(argv[i], "mark=", 5)) {
            /* A Thumb function's symbol has bit 0 set; its first instruction does not. */
            mark = strtoull(argv[i] + 5, NULL, 0) & ~(uint64_t)1;
            have_mark = true;
        }
        else if (!strcmp(argv[i], "per-insn=on")) per_insn = true;
        else { fprintf(stderr, "insn_marks: unknown argument %s\n", argv[i]); return -1; }
    if (!have_mark) { fputs("insn_marks: needs mark=0xADDR\n", stderr); return -1; }
    qemu_plugin_register_vcpu_tb_trans_cb(id, tb_trans);
    qemu_plugin_register_atexit_cb(id, on_exit_cb, NULL);
    return 0;
}
