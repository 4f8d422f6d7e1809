#include <forest_slam/eval/json_writer.h>

#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace forest_slam::eval
{
void JsonWriter::newline()
{
	os_ << '\n';
	for (size_t i = 0; i < stack_.size(); i++) os_ << "  ";
}

void JsonWriter::beforeValue()
{
	if (after_key_)
	{
		after_key_ = false;
		return;
	}
	if (!stack_.empty())
	{
		if (stack_.back().is_object)
			throw std::logic_error(
			    "JsonWriter: value in an object needs a key");
		if (!stack_.back().empty) os_ << ',';
		stack_.back().empty = false;
		newline();
	}
}

JsonWriter& JsonWriter::key(const std::string& name)
{
	if (stack_.empty() || !stack_.back().is_object || after_key_)
		throw std::logic_error("JsonWriter: key outside an object");
	if (!stack_.back().empty) os_ << ',';
	stack_.back().empty = false;
	newline();
	os_ << '"' << escape(name) << "\": ";
	after_key_ = true;
	return *this;
}

JsonWriter& JsonWriter::beginObject()
{
	beforeValue();
	os_ << '{';
	stack_.push_back({true, true});
	return *this;
}

JsonWriter& JsonWriter::endObject()
{
	if (stack_.empty() || !stack_.back().is_object || after_key_)
		throw std::logic_error("JsonWriter: unbalanced endObject");
	const bool empty = stack_.back().empty;
	stack_.pop_back();
	if (!empty) newline();
	os_ << '}';
	if (stack_.empty()) os_ << '\n';
	return *this;
}

JsonWriter& JsonWriter::beginArray()
{
	beforeValue();
	os_ << '[';
	stack_.push_back({false, true});
	return *this;
}

JsonWriter& JsonWriter::endArray()
{
	if (stack_.empty() || stack_.back().is_object)
		throw std::logic_error("JsonWriter: unbalanced endArray");
	const bool empty = stack_.back().empty;
	stack_.pop_back();
	if (!empty) newline();
	os_ << ']';
	return *this;
}

JsonWriter& JsonWriter::value(double v)
{
	beforeValue();
	if (!std::isfinite(v))
	{
		os_ << "null";
		return *this;
	}
	char buf[64];
	std::snprintf(buf, sizeof(buf), "%.15g", v);
	os_ << buf;
	return *this;
}

JsonWriter& JsonWriter::value(long long v)
{
	beforeValue();
	os_ << v;
	return *this;
}

JsonWriter& JsonWriter::value(bool v)
{
	beforeValue();
	os_ << (v ? "true" : "false");
	return *this;
}

JsonWriter& JsonWriter::value(const std::string& v)
{
	beforeValue();
	os_ << '"' << escape(v) << '"';
	return *this;
}

JsonWriter& JsonWriter::null()
{
	beforeValue();
	os_ << "null";
	return *this;
}

std::string JsonWriter::escape(const std::string& s)
{
	std::string out;
	for (unsigned char c : s)
	{
		switch (c)
		{
			case '"':
				out += "\\\"";
				break;
			case '\\':
				out += "\\\\";
				break;
			case '\n':
				out += "\\n";
				break;
			case '\r':
				out += "\\r";
				break;
			case '\t':
				out += "\\t";
				break;
			default:
				if (c < 0x20)
				{
					char buf[8];
					std::snprintf(buf, sizeof(buf), "\\u%04x", c);
					out += buf;
				}
				else
					out += static_cast<char>(c);
		}
	}
	return out;
}

}  // namespace forest_slam::eval
