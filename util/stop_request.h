// A request to stop long work, made by SIGINT or SIGTERM (the CLI's handler records it:
// cli/interrupt.h). Process-wide on purpose: a signal handler can reach nothing else, and
// the loops that must notice it within a second live in every layer (the space scan, the
// window planner, import, the stages' per-object loops), none of which is handed a token
// through its interface. Reading it is one relaxed atomic load: cheap enough for any loop.
#pragma once

#include <atomic>

#include "util/status.h"

namespace shadowcull {

// The signal that asked to stop, or 0.
int stopSignal();
inline bool stopRequested() { return stopSignal() != 0; }

// Records `signal` (async-signal-safe: a lock-free atomic store). 0 forgets it (tests).
void requestStop(int signal);

// Ok, or an Interrupted error naming the signal ("interrupted by Ctrl-C (SIGINT)"): the
// caller returns it as it is, and whoever removes the temporaries says so.
Status stopStatus();

// The temporary a one-file atomic write has in hand (writeFileAtomic, io/chunk_writer.h):
// for the commands that end at once on a signal (diff, merge, report, sweep's files), whose
// handler removes it before the process ends, so that no `.NAME.shadowcull-tmp` is left. One
// at a time: while one is held, holdTemporary() by another thread returns false and that
// write is not covered (the bake's own writes are staged and removed by the bake itself).
bool holdTemporary(const char* path);
void releaseTemporary();
// Async-signal-safe: unlink(2) of the held temporary, if any.
void removeHeldTemporary();

}  // namespace shadowcull
