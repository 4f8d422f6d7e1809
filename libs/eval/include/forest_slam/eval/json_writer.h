#pragma once
// Minimal streaming JSON writer for the evaluation reports: no dependency,
// stable key order, NaN/inf written as null (JSON has no NaN).
#include <ostream>
#include <string>
#include <vector>

namespace forest_slam::eval
{
class JsonWriter
{
   public:
	explicit JsonWriter(std::ostream& os) : os_(os) {}

	JsonWriter& beginObject();
	JsonWriter& endObject();
	JsonWriter& beginArray();
	JsonWriter& endArray();
	/** Next value is the member `name` of the current object. */
	JsonWriter& key(const std::string& name);

	JsonWriter& value(double v);  ///< %.15g; non-finite -> null
	JsonWriter& value(int v) { return value(static_cast<long long>(v)); }
	JsonWriter& value(long long v);
	JsonWriter& value(size_t v) { return value(static_cast<long long>(v)); }
	JsonWriter& value(bool v);
	JsonWriter& value(const std::string& v);
	JsonWriter& value(const char* v) { return value(std::string(v)); }
	JsonWriter& null();

	/** key(name).value(v) */
	template <typename T>
	JsonWriter& kv(const std::string& name, const T& v)
	{
		key(name);
		return value(v);
	}

	static std::string escape(const std::string& s);

   private:
	void beforeValue();
	void newline();
	std::ostream& os_;
	struct Level
	{
		bool is_object;
		bool empty;
	};
	std::vector<Level> stack_;
	bool after_key_ = false;
};

}  // namespace forest_slam::eval
