#include "core/binary_io.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <string>

namespace genscene {
namespace {

TEST(BinaryIo, LoadsLittleAndBigEndianWords) {
  const std::string bytes("\x01\x02\x03\x04\xff", 5);
  EXPECT_EQ(LoadLE32(bytes, 0), 0x04030201u);
  EXPECT_EQ(LoadBE32(bytes, 0), 0x01020304u);
  EXPECT_EQ(LoadLE32(bytes, 1), 0xff040302u);
  EXPECT_EQ(LoadBE32(bytes, 1), 0x020304ffu);
}

TEST(BinaryIo, LoadPastTheEndIsNothing) {
  const std::string bytes("\x01\x02\x03\x04", 4);
  EXPECT_FALSE(LoadLE32(bytes, 1).has_value());
  EXPECT_FALSE(LoadBE32(bytes, 4).has_value());
  EXPECT_FALSE(LoadLE32(bytes, 5).has_value());
  // An offset near SIZE_MAX must not wrap around into the string.
  EXPECT_FALSE(LoadLE32(bytes, SIZE_MAX - 1).has_value());
  EXPECT_FALSE(LoadBE32(std::string(), 0).has_value());
}

TEST(BinaryIo, ReaderNamesTheFileAndFieldWhenTruncated) {
  std::string data;
  PutBinary(data, uint32_t{7});
  PutBinary(data, uint16_t{9});
  BinaryReader reader(data, "volume.gsv", "TSDF");
  EXPECT_EQ(reader.Get<uint32_t>("count"), 7u);
  EXPECT_EQ(reader.remaining(), 2u);
  try {
    reader.Get<uint32_t>("block index");
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "volume.gsv: truncated TSDF file (6 bytes) while reading block index");
  }
}

}  // namespace
}  // namespace genscene
