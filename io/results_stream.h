// A results file (io/results_file.h) read one chunk, and within it one object, at a time: for
// a reader whose memory must grow neither with the file nor with its largest chunk (merge).
// Only the writer's layout is read so (the lines writeResults gives); a file laid out
// otherwise is left to the whole-file reader, which gives the same model or the error.
#pragma once

#include <functional>
#include <optional>
#include <string>

#include "io/results_file.h"

namespace shadowcull::results {

// What a streamed reading hands over of each chunk, in file order: `begin` with its name,
// `object` with each of its objects, then `end` with the rest of it (its name, "simulated"
// and "savings"; no objects). Each part has passed the whole-file reader's checks when it is
// handed over, the chunk as a whole when `end` is; a reading that ends in std::nullopt may
// have handed over parts of a chunk it then found out of the layout. An empty function: the
// part is read, checked and dropped. An error that a part returns ends the reading as is.
struct ChunkParts {
    std::function<Status(const std::string& chunk)> begin;
    std::function<Status(ObjectRecord& object)> object;
    std::function<Status(ChunkRecord& rest)> end;
};

// Reads a results file in writeResults' layout, handing each chunk over in parts; the
// result is the file without its chunks, read by parseResults (so its summary is a file's
// without chunks unless it has one). std::nullopt (no error) when the file is not laid out
// as the writer lays it out (edited by hand, pretty-printed otherwise, no chunks, a key
// given twice, not a regular file or too large): read it whole then (readResultsFile),
// which gives the same model or the error. Checks "no chunk twice" as the whole-file
// reader does. Memory: one object's text and record (and the file's part after the chunks).
Expected<std::optional<ResultsFile>> streamResultsFile(const std::string& path, const ChunkParts& parts);

// The same with each chunk whole, assembled from its parts (memory follows the largest chunk).
using ChunkVisitor = std::function<Status(ChunkRecord& chunk)>;
Expected<std::optional<ResultsFile>> streamResultsFile(const std::string& path, const ChunkVisitor& chunk);

}  // namespace shadowcull::results
