// libFuzzer custom mutator shared by the fuzz targets (their inputs are, or hold, text with
// numbers in it). With probability 1/3 it replaces one number of the input by an extreme
// value: huge, tiny, denormal, non-finite, negative zero, or just past an integer type's
// range. Those are what break readers (issue 11: such a mutator found 63 crashes in 600
// runs), and byte-level mutations rarely turn "0.3" into "1e308". Otherwise, or when the
// input holds no number, libFuzzer's own mutations run (dictionary and comparisons too).

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <iterator>
#include <random>
#include <utility>
#include <vector>

extern "C" size_t LLVMFuzzerMutate(uint8_t* data, size_t size, size_t maxSize);

namespace {

const char* const kExtremes[] = {"1e308", "-1e308", "7e9",  "1e20", "2e18",  "1e-300",     "4.9e-324", "nan",
                                 "inf",   "-inf",   "-0",   "0",    "65535", "2147483648", "-1",       "1e-45"};

bool isDigit(uint8_t c) { return c >= '0' && c <= '9'; }
bool isWordChar(uint8_t c) { return isDigit(c) || (c | 0x20) - 'a' < 26u || c == '_' || c == '.'; }

// [begin, end) of each number written in decimal: [sign] digits [. digits] [e [sign] digits],
// or nan / inf, not inside a word (the 0 of "row0" is a name, not a number).
std::vector<std::pair<size_t, size_t>> findNumbers(const uint8_t* d, size_t n) {
    std::vector<std::pair<size_t, size_t>> out;
    for (size_t i = 0; i < n;) {
        if (i > 0 && isWordChar(d[i - 1])) {
            ++i;
            continue;
        }
        size_t k = i;
        if (d[k] == '-' || d[k] == '+') ++k;
        bool number = false;
        if (n - k >= 3 && (!std::memcmp(d + k, "nan", 3) || !std::memcmp(d + k, "inf", 3)) &&
            (n - k == 3 || !isWordChar(d[k + 3]))) {
            k += 3;
            number = true;
        } else {
            for (; k < n && (isDigit(d[k]) || d[k] == '.'); ++k) number |= isDigit(d[k]);
            if (number && k < n && (d[k] | 0x20) == 'e') {
                size_t e = k + 1;
                if (e < n && (d[e] == '-' || d[e] == '+')) ++e;
                if (e < n && isDigit(d[e])) {
                    k = e;
                    while (k < n && isDigit(d[k])) ++k;
                }
            }
        }
        if (number) out.emplace_back(i, k);
        i = number ? k : i + 1;
    }
    return out;
}

}  // namespace

extern "C" size_t LLVMFuzzerCustomMutator(uint8_t* data, size_t size, size_t maxSize, unsigned int seed) {
    std::minstd_rand rng(seed);
    if (rng() % 3 == 0) {
        const std::vector<std::pair<size_t, size_t>> numbers = findNumbers(data, size);
        if (!numbers.empty()) {
            const auto [begin, end] = numbers[rng() % numbers.size()];
            const char* value = kExtremes[rng() % std::size(kExtremes)];
            const size_t length = std::strlen(value), newSize = size - (end - begin) + length;
            if (newSize <= maxSize) {
                std::memmove(data + begin + length, data + end, size - end);
                std::memcpy(data + begin, value, length);
                return newSize;
            }
        }
    }
    return LLVMFuzzerMutate(data, size, maxSize);
}
