// The MicroPython VM options the firmware's timing rests on, for every build that runs it:
// both board definitions include this, and so does the emulated Cortex-M4F's build
// (host_emulator/runtimes/m4f/boards/M4F_INS/mpconfigboard.mk), so that it counts the
// instructions of the same VM.

// MicroPython's count of the bytes allocated (micropython.mem_total): the firmware looks at
// the heap (gc.mem_free, a scan of ~140,000 instructions) only when what its rare allocating
// steps took may have brought it near its reserve (firmware/app.py, _heap_room). The count
// needs the sizes at every free.
#define MICROPY_MEM_STATS                   (1)
#define MICROPY_MALLOC_USES_ALLOCATED_SIZE  (1)

// The cache of map look-ups (py/map.c): an entry per (name >> 2) modulo its size, a name's
// object being (qstr << 3) | 2, so only every other entry ever holds a name: the default 128
// give the ~100 names a tick looks up 64 places, and the names that share one evict each
// other (one name more in the frozen firmware moved a tick by +-4 %). 1,024 entries (896 B
// more of RAM) give them 512: a tick 14 % shorter on the image (docs/image.md).
#define MICROPY_OPT_MAP_LOOKUP_CACHE_SIZE   (1024)
