// A record (core/common/record.h) to and from its proto message by
// reflection on field names: the message has one field per table field,
// of the same name and a matching type (int32; int64; double; bool; string;
// repeated double for a list of doubles or an Eigen vector; repeated int32;
// repeated string; string or bool for a derived field; for (key, text)
// pairs, a repeated message with string fields `key` and `value`; for an enumerator,
// a proto enum whose value 0 is <PREFIX>UNSPECIFIED and whose value for the
// record's text t is <PREFIX> + upper(t); reading UNSPECIFIED or a value this
// build does not know leaves the record's value). A double field with
// presence (`optional double`) is absent for NaN and reads as NaN when
// absent (older senders did not have it). The message may hold more
// fields (the row's key: job, attempt, index), which these functions leave
// alone. So the conversions name no field; a field added to a table and
// missing from its message is found by RecordProtoMismatch, which
// tests/service/records_test.cc asserts is empty for every record, and is a
// crash (TG_CHECK) the first time a conversion meets it, never a silent drop.
//
// Header only, used by the coordinator (server/service/convert.cc) and the
// worker (worker/study_runner.cc). Thread safety: plain functions.
#ifndef TOTALGRAD_RUNTIME_RECORD_PROTO_H_
#define TOTALGRAD_RUNTIME_RECORD_PROTO_H_

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <google/protobuf/descriptor.h>
#include <google/protobuf/message.h>

#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "core/common/check.h"
#include "core/common/record.h"

namespace totalgrad::record_proto {

namespace internal {

// The prefix of a proto enum's value names ("JOB_STATE_"): its value 0 is
// "<prefix>UNSPECIFIED", as every enum of the API has it; "" when it is not.
// A record's enumerator text t is the value "<prefix>" + upper(t)
// ("lease_lost" <-> ATTEMPT_STATE_LEASE_LOST).
inline std::string EnumPrefix(const google::protobuf::EnumDescriptor& type) {
  const google::protobuf::EnumValueDescriptor* zero = type.FindValueByNumber(0);
  constexpr absl::string_view kUnspecified = "UNSPECIFIED";
  if (zero == nullptr || !absl::EndsWith(zero->name(), kUnspecified)) return "";
  return std::string(zero->name().substr(0, zero->name().size() - kUnspecified.size()));
}

// The proto type and cardinality a field of `type` must have.
inline bool Matches(record::FieldType type, const google::protobuf::FieldDescriptor& fd) {
  using google::protobuf::FieldDescriptor;
  using record::FieldType;
  const bool repeated = fd.is_repeated();
  switch (type) {
    case FieldType::kInt: return !repeated && fd.cpp_type() == FieldDescriptor::CPPTYPE_INT32;
    case FieldType::kInt64: return !repeated && fd.cpp_type() == FieldDescriptor::CPPTYPE_INT64;
    case FieldType::kDouble: return !repeated && fd.cpp_type() == FieldDescriptor::CPPTYPE_DOUBLE;
    case FieldType::kBool:
    case FieldType::kDerivedBool:
      return !repeated && fd.cpp_type() == FieldDescriptor::CPPTYPE_BOOL;
    case FieldType::kEnum:
      return !repeated && fd.cpp_type() == FieldDescriptor::CPPTYPE_ENUM &&
             !EnumPrefix(*fd.enum_type()).empty();
    case FieldType::kText:
    case FieldType::kDerivedText:
      return !repeated && fd.cpp_type() == FieldDescriptor::CPPTYPE_STRING;
    case FieldType::kDoubles:
    case FieldType::kVector:
      return repeated && fd.cpp_type() == FieldDescriptor::CPPTYPE_DOUBLE;
    case FieldType::kInts: return repeated && fd.cpp_type() == FieldDescriptor::CPPTYPE_INT32;
    case FieldType::kTexts: return repeated && fd.cpp_type() == FieldDescriptor::CPPTYPE_STRING;
    case FieldType::kTextPairs: {
      if (!repeated || fd.cpp_type() != FieldDescriptor::CPPTYPE_MESSAGE) return false;
      const FieldDescriptor* key = fd.message_type()->FindFieldByName("key");
      const FieldDescriptor* value = fd.message_type()->FindFieldByName("value");
      return key != nullptr && value != nullptr && !key->is_repeated() &&
             !value->is_repeated() && key->cpp_type() == FieldDescriptor::CPPTYPE_STRING &&
             value->cpp_type() == FieldDescriptor::CPPTYPE_STRING;
    }
  }
  return false;
}

template <typename R>
const google::protobuf::FieldDescriptor& ProtoField(const record::Field<R>& field,
                                                    const google::protobuf::Descriptor& message) {
  const google::protobuf::FieldDescriptor* fd = message.FindFieldByName(field.name);
  // A programmer error (tests/service/records_test.cc catches it first).
  TG_CHECK(fd != nullptr && Matches(field.type(), *fd));
  return *fd;
}

}  // namespace internal

// "" when every field of `table` has a field of its name and a matching type
// in `message`; else what is wrong with the first that has not.
template <typename R>
std::string RecordProtoMismatch(const record::FieldTable<R>& table,
                                const google::protobuf::Descriptor& message) {
  for (const auto& field : table) {
    const google::protobuf::FieldDescriptor* fd = message.FindFieldByName(field.name);
    if (fd == nullptr) {
      return absl::StrCat(message.full_name(), " has no field '", field.name, "'");
    }
    if (!internal::Matches(field.type(), *fd)) {
      return absl::StrCat(message.full_name(), ".", field.name, " is ",
                          fd->is_repeated() ? "repeated " : "", fd->cpp_type_name(),
                          ", which does not hold the record's value");
    }
  }
  return "";
}

// Sets every table field of *out (derived ones included); repeated fields
// are replaced.
template <typename R>
void RecordToProto(const record::FieldTable<R>& table, const R& r, google::protobuf::Message* out) {
  using record::FieldType;
  const google::protobuf::Reflection& reflection = *out->GetReflection();
  for (const auto& field : table) {
    const google::protobuf::FieldDescriptor* fd = &internal::ProtoField(field, *out->GetDescriptor());
    switch (field.type()) {
      case FieldType::kInt: reflection.SetInt32(out, fd, field.template Get<int>(r)); break;
      case FieldType::kInt64: reflection.SetInt64(out, fd, field.template Get<int64_t>(r)); break;
      case FieldType::kDerivedBool: reflection.SetBool(out, fd, field.DeriveBool(r)); break;
      case FieldType::kEnum: {
        const std::string text = field.EnumToText(r);
        const google::protobuf::EnumValueDescriptor* value = fd->enum_type()->FindValueByName(
            internal::EnumPrefix(*fd->enum_type()) + absl::AsciiStrToUpper(text));
        // A programmer error: the C++ enum has a name the proto enum lacks
        // (tests/service/records_test.cc sends every value of every table).
        TG_CHECK(value != nullptr);
        reflection.SetEnum(out, fd, value);
        break;
      }
      case FieldType::kDouble: {
        const double v = field.template Get<double>(r);
        if (fd->has_presence() && std::isnan(v)) {
          reflection.ClearField(out, fd);
        } else {
          reflection.SetDouble(out, fd, v);
        }
        break;
      }
      case FieldType::kBool: reflection.SetBool(out, fd, field.template Get<bool>(r)); break;
      case FieldType::kText: reflection.SetString(out, fd, field.template Get<std::string>(r)); break;
      case FieldType::kDerivedText: reflection.SetString(out, fd, field.Derive(r)); break;
      case FieldType::kInts:
        reflection.ClearField(out, fd);
        for (int v : field.template Get<std::vector<int>>(r)) reflection.AddInt32(out, fd, v);
        break;
      case FieldType::kTexts:
        reflection.ClearField(out, fd);
        for (const std::string& v : field.template Get<std::vector<std::string>>(r)) {
          reflection.AddString(out, fd, v);
        }
        break;
      case FieldType::kDoubles:
      case FieldType::kVector:
        reflection.ClearField(out, fd);
        for (double v : record::DoublesOf(field, r)) reflection.AddDouble(out, fd, v);
        break;
      case FieldType::kTextPairs: {
        reflection.ClearField(out, fd);
        const google::protobuf::Descriptor& pair = *fd->message_type();
        for (const auto& [key, text] : field.template Get<record::TextPairs>(r)) {
          google::protobuf::Message* entry = reflection.AddMessage(out, fd);
          const google::protobuf::Reflection& entry_reflection = *entry->GetReflection();
          entry_reflection.SetString(entry, pair.FindFieldByName("key"), key);
          entry_reflection.SetString(entry, pair.FindFieldByName("value"), text);
        }
        break;
      }
    }
  }
}

// Reads every non-derived table field from `message` into *r.
template <typename R>
void RecordFromProto(const record::FieldTable<R>& table, const google::protobuf::Message& message,
                     R* r) {
  using record::FieldType;
  const google::protobuf::Reflection& reflection = *message.GetReflection();
  for (const auto& field : table) {
    if (field.derived()) continue;
    const google::protobuf::FieldDescriptor* fd =
        &internal::ProtoField(field, *message.GetDescriptor());
    switch (field.type()) {
      case FieldType::kInt: field.template Get<int>(*r) = reflection.GetInt32(message, fd); break;
      case FieldType::kInt64:
        field.template Get<int64_t>(*r) = reflection.GetInt64(message, fd);
        break;
      case FieldType::kEnum: {
        // UNSPECIFIED (a sender that did not set it) and a value this build
        // does not know (a newer sender's) leave *r's value: there is no
        // enumerator to put there.
        const google::protobuf::EnumValueDescriptor* value = reflection.GetEnum(message, fd);
        const std::string prefix = internal::EnumPrefix(*fd->enum_type());
        if (value->number() != 0 && absl::StartsWith(value->name(), prefix)) {
          field.ParseEnum(absl::AsciiStrToLower(value->name().substr(prefix.size())), r);
        }
        break;
      }
      case FieldType::kDouble:
        field.template Get<double>(*r) = fd->has_presence() && !reflection.HasField(message, fd)
                                             ? std::numeric_limits<double>::quiet_NaN()
                                             : reflection.GetDouble(message, fd);
        break;
      case FieldType::kBool: field.template Get<bool>(*r) = reflection.GetBool(message, fd); break;
      case FieldType::kText:
        field.template Get<std::string>(*r) = reflection.GetString(message, fd);
        break;
      case FieldType::kInts: {
        std::vector<int>& values = field.template Get<std::vector<int>>(*r);
        values.clear();
        for (int i = 0; i < reflection.FieldSize(message, fd); ++i) {
          values.push_back(reflection.GetRepeatedInt32(message, fd, i));
        }
        break;
      }
      case FieldType::kTexts: {
        std::vector<std::string>& values = field.template Get<std::vector<std::string>>(*r);
        values.clear();
        for (int i = 0; i < reflection.FieldSize(message, fd); ++i) {
          values.push_back(reflection.GetRepeatedString(message, fd, i));
        }
        break;
      }
      case FieldType::kDoubles:
      case FieldType::kVector: {
        std::vector<double> values;
        for (int i = 0; i < reflection.FieldSize(message, fd); ++i) {
          values.push_back(reflection.GetRepeatedDouble(message, fd, i));
        }
        record::SetDoubles(field, std::move(values), r);
        break;
      }
      case FieldType::kTextPairs: {
        record::TextPairs& values = field.template Get<record::TextPairs>(*r);
        values.clear();
        const google::protobuf::Descriptor& pair = *fd->message_type();
        for (int i = 0; i < reflection.FieldSize(message, fd); ++i) {
          const google::protobuf::Message& entry = reflection.GetRepeatedMessage(message, fd, i);
          const google::protobuf::Reflection& entry_reflection = *entry.GetReflection();
          values.emplace_back(entry_reflection.GetString(entry, pair.FindFieldByName("key")),
                              entry_reflection.GetString(entry, pair.FindFieldByName("value")));
        }
        break;
      }
      case FieldType::kDerivedText:
      case FieldType::kDerivedBool: break;
    }
  }
}

}  // namespace totalgrad::record_proto

#endif  // TOTALGRAD_RUNTIME_RECORD_PROTO_H_
