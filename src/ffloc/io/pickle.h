#pragma once

#include <cstdint>
#include <deque>
#include <string>
#include <utility>
#include <vector>

namespace ffloc::pickle {

// A value built by the pickle machine. Python objects are not executed: a call (REDUCE, NEWOBJ)
// becomes an kObject node recording the callable and its arguments, and a persistent id a
// kPersistentId node, for the caller to interpret. The only call evaluated is
// collections.OrderedDict(), which yields a kDict so that SETITEMS can fill it.
enum class Kind {
  kNone,
  kBool,
  kInt,
  kFloat,
  kString,  // str (UTF-8) and bytes alike
  kTuple,
  kList,  // also sets and frozensets
  kDict,
  kGlobal,
  kObject,
  kPersistentId,
};

struct Value {
  Kind kind = Kind::kNone;
  bool boolean = false;
  int64_t integer = 0;
  double number = 0.0;
  std::string text;  // kString; kGlobal: "module.name"
  std::vector<const Value*> items;  // kTuple, kList; kObject: call arguments
  std::vector<std::pair<const Value*, const Value*>> entries;  // kDict; kObject: set items
  const Value* callable = nullptr;  // kObject
  const Value* state = nullptr;     // kObject: the BUILD argument
  const Value* persistent_id = nullptr;  // kPersistentId
};

// The result of unpickling; values live in (and are owned by) the arena, so the graph may share
// nodes or even contain cycles without recursion when it is destroyed.
struct Unpickled {
  std::deque<Value> arena;
  const Value* root = nullptr;
};

// Runs a protocol 2-5 pickle (the binary opcodes that torch.save() and Python's pickler emit,
// see docs/weights.md). Everything is bounds-checked: a truncated stream, an unknown opcode,
// stack underflow or a missing memo entry raise InputError naming `source` and the byte offset.
Unpickled unpickle(const uint8_t* data, size_t size, const std::string& source);

// Helpers for walking the result; they return nullptr / false on a kind mismatch.
const Value* dictGet(const Value* dict, const std::string& key);
bool isString(const Value* value, const std::string& text);
bool isGlobal(const Value* value, const std::string& qualified_name);

// Builds a protocol 2 pickle opcode by opcode, from opcodes Python's own pickler writes, so that
// Python's pickle.load reads it: the split file of Indoor6, whose tools are Python, and the
// tests' hand-made torch.save() archives. Unlike Python, it writes no memo entries (they only
// matter for shared objects) and every int as BININT (Python picks the shortest form).
struct Writer {
  std::string bytes = std::string("\x80\x02", 2);  // PROTO 2

  void op(char opcode) { bytes.push_back(opcode); }
  void text(const std::string& utf8);  // a str
  void integer(int32_t value);
  void stringList(const std::vector<std::string>& values);
  void integerList(const std::vector<int32_t>& values);
  std::string finish() const { return bytes + "."; }
};

}  // namespace ffloc::pickle
