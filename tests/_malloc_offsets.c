/* A malloc for LD_PRELOAD that places every heap block at an offset of 0, 16, 32 or 48 bytes
   from a 64-byte boundary (tests/test_step_reproducible.py): each block's offset drawn from a
   generator seeded by HQP_MALLOC_SEED (0: every block 64-byte aligned). glibc's own blocks are
   16-byte aligned, and whether one is also 32- or 64-byte aligned follows the allocation
   history of the process; this makes that alignment vary block by block, on purpose. */
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

extern void *__libc_memalign(size_t alignment, size_t size);
extern void __libc_free(void *ptr);

static const uintptr_t kMagic = 0x5eedfacecafebeefULL;
static uint64_t state;
static int seeded;

static uintptr_t next_offset(void) {
  if (!seeded) {
    const char *s = getenv("HQP_MALLOC_SEED");
    state = s ? strtoull(s, NULL, 10) : 0;
    seeded = 1;
  }
  if (!state) return 0;
  state ^= state << 13; /* xorshift64 */
  state ^= state >> 7;
  state ^= state << 17;
  return (uintptr_t)((state >> 11) & 3) * 16;
}

/* Block header, below the pointer returned: [size, magic, raw pointer]. */
static void *place(size_t size, size_t alignment) {
  if (alignment < 64) alignment = 64;
  char *raw = __libc_memalign(alignment, size + alignment + 32 + 64);
  if (!raw) return NULL;
  uintptr_t p = ((uintptr_t)raw + 32 + alignment - 1) / alignment * alignment;
  if (alignment == 64) p += next_offset();
  uintptr_t *h = (uintptr_t *)p;
  h[-1] = (uintptr_t)raw;
  h[-2] = kMagic;
  h[-3] = size;
  return (void *)p;
}

void *malloc(size_t size) { return place(size, 64); }

void free(void *ptr) {
  if (!ptr) return;
  uintptr_t *h = ptr;
  if (h[-2] != kMagic) { /* not ours (none expected) */
    __libc_free(ptr);
    return;
  }
  h[-2] = 0;
  __libc_free((void *)h[-1]);
}

void *calloc(size_t n, size_t size) {
  void *p = place(n * size, 64);
  if (p) memset(p, 0, n * size);
  return p;
}

void *realloc(void *ptr, size_t size) {
  if (!ptr) return malloc(size);
  if (!size) {
    free(ptr);
    return NULL;
  }
  size_t old = ((uintptr_t *)ptr)[-3];
  void *q = malloc(size);
  if (!q) return NULL;
  memcpy(q, ptr, old < size ? old : size);
  free(ptr);
  return q;
}

void *memalign(size_t alignment, size_t size) { return place(size, alignment); }
void *aligned_alloc(size_t alignment, size_t size) { return place(size, alignment); }
int posix_memalign(void **out, size_t alignment, size_t size) {
  void *p = place(size, alignment);
  if (!p) return 12; /* ENOMEM */
  *out = p;
  return 0;
}
void *valloc(size_t size) { return place(size, 4096); }
void *pvalloc(size_t size) { return place((size + 4095) & ~(size_t)4095, 4096); }
size_t malloc_usable_size(void *ptr) { return ptr ? ((uintptr_t *)ptr)[-3] : 0; }
