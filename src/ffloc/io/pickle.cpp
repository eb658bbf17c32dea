#include "ffloc/io/pickle.h"

#include <cstdio>
#include <cstring>
#include <unordered_map>

#include "ffloc/core/error.h"

namespace ffloc::pickle {
namespace {

// What the machine may build, counted in bytes as it goes and never given back: values, stack
// slots, references held by tuples, lists and dicts, strings and memo entries. A real state
// dict's pickle builds a few MB (DUSt3R's 2.2 GB checkpoint: a 100 KB pickle), but every
// one-byte opcode builds a value of ~130 bytes, and REDUCE, DUP and BINGET can copy large tuples
// over and over: without a bound, a 16 MB pickle took 1.5 GB, and a crafted one could take
// any amount.
constexpr size_t kMaxMemoryBytes = size_t{256} << 20;

class Machine {
 public:
  Machine(const uint8_t* data, size_t size, const std::string& source)
      : data_(data), size_(size), source_(source) {}

  Unpickled run();

 private:
  [[noreturn]] void fail(const std::string& what) const {
    throwInputError(source_, 0, "pickle offset " + std::to_string(opcode_offset_) + ": " + what);
  }

  const uint8_t* take(size_t count) {
    if (size_ - at_ < count) fail("truncated pickle stream");
    const uint8_t* bytes = data_ + at_;
    at_ += count;
    return bytes;
  }
  uint64_t takeLe(size_t count) {
    const uint8_t* bytes = take(count);
    uint64_t value = 0;
    for (size_t i = count; i-- > 0;) value = (value << 8) | bytes[i];
    return value;
  }
  std::string takeLine() {
    const void* newline = std::memchr(data_ + at_, '\n', size_ - at_);
    if (!newline) fail("unterminated GLOBAL line");
    const size_t length = static_cast<const uint8_t*>(newline) - (data_ + at_);
    std::string line(reinterpret_cast<const char*>(data_ + at_), length);
    at_ += length + 1;
    return line;
  }
  std::string takeText(uint64_t length) {
    if (length > size_ - at_) fail("string of " + std::to_string(length) + " bytes runs past the end");
    charge(length);
    const uint8_t* bytes = take(length);
    return std::string(reinterpret_cast<const char*>(bytes), length);
  }

  void charge(size_t bytes) {
    if (bytes > kMaxMemoryBytes - used_bytes_)
      fail("the pickle builds more than " + std::to_string(kMaxMemoryBytes >> 20) +
           " MB of objects, far beyond a state dict's (refused to bound memory)");
    used_bytes_ += bytes;
  }
  // Charged for `count` references (stack slots, items, entries).
  void chargeReferences(size_t count) { charge(count * 2 * sizeof(Value*)); }

  Value* make(Kind kind) {
    charge(sizeof(Value));
    Value& value = result_.arena.emplace_back();
    value.kind = kind;
    return &value;
  }
  Value* makeInt(int64_t integer) {
    Value* value = make(Kind::kInt);
    value->integer = integer;
    return value;
  }
  Value* makeString(std::string text) {
    Value* value = make(Kind::kString);
    value->text = std::move(text);
    return value;
  }

  void push(Value* value) {
    chargeReferences(1);
    stack_.push_back(value);
  }
  Value* pop() {
    if (stack_.size() <= floor()) fail("stack underflow");
    Value* value = stack_.back();
    stack_.pop_back();
    return value;
  }
  Value* top() {
    if (stack_.size() <= floor()) fail("stack underflow");
    return stack_.back();
  }
  size_t floor() const { return marks_.empty() ? 0 : marks_.back(); }
  // Pops everything above the topmost MARK, and the mark.
  std::vector<Value*> popToMark() {
    if (marks_.empty()) fail("no MARK on the stack");
    const size_t mark = marks_.back();
    marks_.pop_back();
    std::vector<Value*> items(stack_.begin() + mark, stack_.end());
    stack_.resize(mark);
    return items;
  }
  Value* makeTuple(const std::vector<Value*>& items) {
    chargeReferences(items.size());
    Value* tuple = make(Kind::kTuple);
    tuple->items.assign(items.begin(), items.end());
    return tuple;
  }

  void memoize(uint64_t key) {
    charge(kMemoEntryBytes);
    memo_[key] = top();
  }
  Value* recall(uint64_t key) {
    const auto found = memo_.find(key);
    if (found == memo_.end()) fail("memo key " + std::to_string(key) + " was never stored");
    return found->second;
  }

  void appendItems(Value* target, const std::vector<Value*>& items) {
    if (target->kind != Kind::kList && target->kind != Kind::kObject) {
      fail("APPEND(S) onto a value that is not a list");
    }
    chargeReferences(items.size());
    target->items.insert(target->items.end(), items.begin(), items.end());
  }
  void setItems(Value* target, const std::vector<Value*>& pairs) {
    if (target->kind != Kind::kDict && target->kind != Kind::kObject) {
      fail("SETITEM(S) onto a value that is not a dict");
    }
    if (pairs.size() % 2 != 0) fail("SETITEMS with an odd number of stack items");
    chargeReferences(pairs.size());
    // Duplicated keys are kept in order; readers take the last one, as Python would.
    for (size_t i = 0; i < pairs.size(); i += 2) target->entries.emplace_back(pairs[i], pairs[i + 1]);
  }
  Value* call(Value* callable, Value* arguments) {
    if (arguments->kind != Kind::kTuple) fail("call arguments are not a tuple");
    if (isGlobal(callable, "collections.OrderedDict") && arguments->items.empty()) {
      return make(Kind::kDict);
    }
    Value* object = make(Kind::kObject);
    object->callable = callable;
    chargeReferences(arguments->items.size());
    object->items = arguments->items;
    return object;
  }

  const uint8_t* data_;
  size_t size_;
  const std::string& source_;
  size_t at_ = 0;
  size_t opcode_offset_ = 0;
  Unpickled result_;
  std::vector<Value*> stack_;
  std::vector<size_t> marks_;
  std::unordered_map<uint64_t, Value*> memo_;
  // A node of the memo's hash map: key, value, next pointer, cached hash, bucket slot.
  static constexpr size_t kMemoEntryBytes = 48;
  size_t used_bytes_ = 0;
};

Unpickled Machine::run() {
  while (true) {
    opcode_offset_ = at_;
    const uint8_t opcode = *take(1);
    switch (opcode) {
      case 0x80: {  // PROTO
        const uint8_t protocol = *take(1);
        if (protocol > 5) fail("unsupported pickle protocol " + std::to_string(protocol));
        break;
      }
      case 0x95:  // FRAME: a length hint only
        take(8);
        break;
      case '.': {  // STOP
        result_.root = pop();
        return std::move(result_);
      }
      case '(':  // MARK
        chargeReferences(1);
        marks_.push_back(stack_.size());
        break;
      case '0':  // POP
        pop();
        break;
      case '1':  // POP_MARK
        popToMark();
        break;
      case '2':  // DUP
        push(top());
        break;
      case 'N':
        push(make(Kind::kNone));
        break;
      case 0x88:
      case 0x89: {  // NEWTRUE, NEWFALSE
        Value* value = make(Kind::kBool);
        value->boolean = opcode == 0x88;
        push(value);
        break;
      }
      case 'J':  // BININT
        push(makeInt(static_cast<int32_t>(takeLe(4))));
        break;
      case 'K':  // BININT1
        push(makeInt(static_cast<int64_t>(takeLe(1))));
        break;
      case 'M':  // BININT2
        push(makeInt(static_cast<int64_t>(takeLe(2))));
        break;
      case 0x8a:    // LONG1
      case 0x8b: {  // LONG4
        const uint64_t length = opcode == 0x8a ? takeLe(1) : takeLe(4);
        if (length > 8) fail("integer of " + std::to_string(length) + " bytes does not fit 64 bits");
        uint64_t bits = length == 0 ? 0 : takeLe(length);
        if (length > 0 && length < 8 && (bits >> (8 * length - 1)) & 1) {
          bits |= ~uint64_t{0} << (8 * length);  // sign-extend two's complement
        }
        push(makeInt(static_cast<int64_t>(bits)));
        break;
      }
      case 'G': {  // BINFLOAT, big-endian
        const uint8_t* bytes = take(8);
        uint64_t bits = 0;
        for (int i = 0; i < 8; ++i) bits = (bits << 8) | bytes[i];
        Value* value = make(Kind::kFloat);
        std::memcpy(&value->number, &bits, sizeof(bits));
        push(value);
        break;
      }
      case 'T': {  // BINSTRING (signed length)
        const int32_t length = static_cast<int32_t>(takeLe(4));
        if (length < 0) fail("negative string length");
        push(makeString(takeText(static_cast<uint64_t>(length))));
        break;
      }
      case 'U':     // SHORT_BINSTRING
      case 0x8c:    // SHORT_BINUNICODE
      case 'C':     // SHORT_BINBYTES
        push(makeString(takeText(takeLe(1))));
        break;
      case 'X':  // BINUNICODE
      case 'B':  // BINBYTES
        push(makeString(takeText(takeLe(4))));
        break;
      case 0x8d:  // BINUNICODE8
      case 0x8e:  // BINBYTES8
        push(makeString(takeText(takeLe(8))));
        break;
      case '}':
        push(make(Kind::kDict));
        break;
      case ']':
      case 0x8f:  // EMPTY_SET
        push(make(Kind::kList));
        break;
      case ')':
        push(make(Kind::kTuple));
        break;
      case 't':  // TUPLE
        push(makeTuple(popToMark()));
        break;
      case 0x85:
      case 0x86:
      case 0x87: {  // TUPLE1..3
        std::vector<Value*> items(opcode - 0x84);
        for (size_t i = items.size(); i-- > 0;) items[i] = pop();
        push(makeTuple(items));
        break;
      }
      case 'l':     // LIST
      case 0x91: {  // FROZENSET
        Value* list = make(Kind::kList);
        const std::vector<Value*> items = popToMark();
        chargeReferences(items.size());
        list->items.assign(items.begin(), items.end());
        push(list);
        break;
      }
      case 'd': {  // DICT
        Value* dict = make(Kind::kDict);
        setItems(dict, popToMark());
        push(dict);
        break;
      }
      case 'a': {  // APPEND
        Value* item = pop();
        appendItems(top(), {item});
        break;
      }
      case 'e':     // APPENDS
      case 0x90: {  // ADDITEMS
        const std::vector<Value*> items = popToMark();
        appendItems(top(), items);
        break;
      }
      case 's': {  // SETITEM
        Value* value = pop();
        Value* key = pop();
        setItems(top(), {key, value});
        break;
      }
      case 'u': {  // SETITEMS
        const std::vector<Value*> pairs = popToMark();
        setItems(top(), pairs);
        break;
      }
      case 'q':  // BINPUT
        memoize(takeLe(1));
        break;
      case 'r':  // LONG_BINPUT
        memoize(takeLe(4));
        break;
      case 0x94:  // MEMOIZE
        memoize(memo_.size());
        break;
      case 'h':  // BINGET
        push(recall(takeLe(1)));
        break;
      case 'j':  // LONG_BINGET
        push(recall(takeLe(4)));
        break;
      case 'c': {  // GLOBAL "module\nname\n"
        const std::string module = takeLine();
        const std::string name = takeLine();
        charge(module.size() + name.size());
        Value* global = make(Kind::kGlobal);
        global->text = module + "." + name;
        push(global);
        break;
      }
      case 0x93: {  // STACK_GLOBAL
        Value* name = pop();
        Value* module = pop();
        if (name->kind != Kind::kString || module->kind != Kind::kString) {
          fail("STACK_GLOBAL operands are not strings");
        }
        charge(module->text.size() + name->text.size());
        Value* global = make(Kind::kGlobal);
        global->text = module->text + "." + name->text;
        push(global);
        break;
      }
      case 'R':     // REDUCE
      case 0x81: {  // NEWOBJ
        Value* arguments = pop();
        Value* callable = pop();
        push(call(callable, arguments));
        break;
      }
      case 0x92: {  // NEWOBJ_EX: keyword arguments are dropped, the object stays opaque
        pop();
        Value* arguments = pop();
        Value* callable = pop();
        push(call(callable, arguments));
        break;
      }
      case 'b': {  // BUILD
        Value* state = pop();
        Value* target = top();
        // A dict's BUILD state only sets attributes (OrderedDict._metadata of a state dict).
        if (target->kind == Kind::kObject) {
          target->state = state;
        } else if (target->kind != Kind::kDict) {
          fail("BUILD on a value that is not an object");
        }
        break;
      }
      case 'Q': {  // BINPERSID
        Value* reference = make(Kind::kPersistentId);
        reference->persistent_id = pop();
        push(reference);
        break;
      }
      default: {
        char name[16];
        std::snprintf(name, sizeof(name), "0x%02x", opcode);
        std::string shown = name;
        if (opcode >= 0x20 && opcode < 0x7f) shown = "'" + std::string(1, char(opcode)) + "' (" + shown + ")";
        fail("unsupported pickle opcode " + shown);
      }
    }
  }
}

}  // namespace

Unpickled unpickle(const uint8_t* data, size_t size, const std::string& source) {
  return Machine(data, size, source).run();
}

const Value* dictGet(const Value* dict, const std::string& key) {
  if (!dict || dict->kind != Kind::kDict) return nullptr;
  for (auto entry = dict->entries.rbegin(); entry != dict->entries.rend(); ++entry) {
    if (isString(entry->first, key)) return entry->second;
  }
  return nullptr;
}

bool isString(const Value* value, const std::string& text) {
  return value && value->kind == Kind::kString && value->text == text;
}

bool isGlobal(const Value* value, const std::string& qualified_name) {
  return value && value->kind == Kind::kGlobal && value->text == qualified_name;
}

namespace {

void appendLittleEndian32(std::string* out, uint32_t value) {
  for (int i = 0; i < 4; ++i) out->push_back(static_cast<char>((value >> (8 * i)) & 0xff));
}

// EMPTY_LIST, then the items: one by APPEND, more between MARK and APPENDS, as Python writes
// them (it splits lists beyond 1,000 items into several MARK ... APPENDS; one reads the same).
template <typename Item, typename WriteItem>
void writeList(Writer* writer, const std::vector<Item>& items, WriteItem write_item) {
  writer->op(']');
  if (items.size() > 1) writer->op('(');
  for (const Item& item : items) write_item(item);
  if (!items.empty()) writer->op(items.size() > 1 ? 'e' : 'a');
}

}  // namespace

void Writer::text(const std::string& utf8) {
  op('X');  // BINUNICODE
  appendLittleEndian32(&bytes, static_cast<uint32_t>(utf8.size()));
  bytes += utf8;
}

void Writer::integer(int32_t value) {
  op('J');  // BININT
  appendLittleEndian32(&bytes, static_cast<uint32_t>(value));
}

void Writer::stringList(const std::vector<std::string>& values) {
  writeList(this, values, [this](const std::string& value) { text(value); });
}

void Writer::integerList(const std::vector<int32_t>& values) {
  writeList(this, values, [this](int32_t value) { integer(value); });
}

}  // namespace ffloc::pickle
