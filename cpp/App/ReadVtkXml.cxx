// The checks of a VTK XML image data file (.vti) before VTK's reader sees
// it, and the reader that tells which samples no piece of the file holds.
#include "ReadVtkXml.h"

#include "ReadChecks.h"

#include "vtkDataArray.h"
#include "vtkObjectFactory.h"
#include "vtkXMLDataElement.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <sstream>

namespace pmcapp
{
namespace
{

// The value of attribute `name` in the XML start tag `tag`, as XML writes
// it: spaces allowed around the '=', the value in double or single
// quotes. False when the tag has no such attribute.
bool FindXmlAttribute(const std::string& tag, const std::string& name, std::string& value)
{
  const auto space = [&tag](size_t i) {
    return i < tag.size() && std::isspace(static_cast<unsigned char>(tag[i]));
  };
  for (size_t at = tag.find(name); at != std::string::npos; at = tag.find(name, at + 1))
  {
    // A whole attribute name, not the end of a longer one.
    if (at > 0 && !space(at - 1))
    {
      continue;
    }
    size_t i = at + name.size();
    while (space(i))
    {
      ++i;
    }
    if (i >= tag.size() || tag[i] != '=')
    {
      continue;
    }
    ++i;
    while (space(i))
    {
      ++i;
    }
    if (i >= tag.size() || (tag[i] != '"' && tag[i] != '\''))
    {
      continue;
    }
    const size_t end = tag.find(tag[i], i + 1);
    value = end == std::string::npos ? "" : tag.substr(i + 1, end - i - 1);
    return true;
  }
  return false;
}

// The bytes of a .vti file its checks read for the XML part (a large
// ASCII FieldData array before the data, or a long comment, pushed the
// tags a 64 KiB or 1 MiB window held out of it, and the checks passed).
const size_t VtiXmlWindow = size_t(1) << 24;

// Where `tag` (as "<ImageData") starts in `xml` from `from` on, outside
// its comments ("<!-- ... -->"; an unclosed one runs to the end);
// npos if nowhere. A tag written in a comment is none: an <ImageData
// Origin="0 0 0"> or an <AppendedData> there was checked in place of the
// real one, and a NaN origin or a cut block passed.
size_t FindTag(const std::string& xml, const std::string& tag, size_t from = 0)
{
  size_t at = xml.find(tag, from);
  size_t open = xml.find("<!--");
  while (at != std::string::npos && open != std::string::npos && open <= at)
  {
    const size_t close = xml.find("-->", open + 4);
    if (close == std::string::npos)
    {
      return std::string::npos; // inside a comment that runs to the end
    }
    if (at < close + 3)
    {
      at = xml.find(tag, close + 3); // inside this comment: look past it
    }
    open = xml.find("<!--", close + 3);
  }
  return at;
}

// The value of attribute `name` in the XML start tag `tag` ("" if absent).
std::string XmlAttribute(const std::string& tag, const std::string& name)
{
  std::string value;
  return FindXmlAttribute(tag, name, value) ? value : "";
}

// The bytes that base64 `text` (whitespace ignored) starts with, at most
// `bytes` of them; fewer where the text ends, pads or is not base64.
std::string Base64Prefix(const std::string& text, size_t bytes)
{
  std::string out;
  unsigned bits = 0;
  int held = 0;
  for (char c : text)
  {
    if (out.size() >= bytes || c == '=')
    {
      break;
    }
    if (std::isspace(static_cast<unsigned char>(c)))
    {
      continue;
    }
    const char* digits = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    const char* at = std::strchr(digits, c);
    if (!at || c == '\0')
    {
      break;
    }
    bits = (bits << 6) | static_cast<unsigned>(at - digits);
    held += 6;
    if (held >= 8)
    {
      held -= 8;
      out.push_back(static_cast<char>((bits >> held) & 0xff));
    }
  }
  return out;
}

// The byte count in an uncompressed block's header (header_type's size,
// the file's byte order); false when `header` is shorter.
bool BlockByteCount(const std::string& header, int headerSize, bool bigEndian,
  unsigned long long& count)
{
  if (header.size() < static_cast<size_t>(headerSize))
  {
    return false;
  }
  count = 0;
  for (int b = 0; b < headerSize; ++b)
  {
    count |= static_cast<unsigned long long>(static_cast<unsigned char>(
               header[static_cast<size_t>(bigEndian ? headerSize - 1 - b : b)]))
      << (8 * b);
  }
  return true;
}

// The base64 characters of an uncompressed block of `count` bytes: VTK 9.1
// encodes the header and the data as one stream (a 40^3 float array with a
// UInt32 header is 4 * ceil(256004 / 3) characters, not the header's 8 plus
// the data's), padded at its end. A header encoded on its own, padded, as
// compressed blocks have it, needs more: a file written so passes too.
unsigned long long Base64BlockSize(int headerSize, unsigned long long count)
{
  return (static_cast<unsigned long long>(headerSize) + count + 2) / 3 * 4;
}

}

vtkStandardNewMacro(vtkPieceCheckingImageDataReader);

// A .vti whose <ImageData> Origin, Spacing or Direction is not 3 (9 for
// Direction) finite numbers: VTK's reader drops an attribute it cannot
// parse ("NaN", "Infinity", a word, too few numbers, none) and uses the
// default (origin 0, spacing 1, identity) without a word, so the surface
// came out at a place and scale the file does not give.
void CheckVtiGeometry(const std::string& path)
{
  const std::string head = FileHead(path, VtiXmlWindow);
  const size_t tag = FindTag(head, "<ImageData");
  const size_t end = tag == std::string::npos ? tag : head.find('>', tag);
  if (end == std::string::npos)
  {
    return;
  }
  const std::string element = head.substr(tag, end - tag);
  for (const auto& attribute : { std::make_pair("Origin", 3), std::make_pair("Spacing", 3),
         std::make_pair("Direction", 9) })
  {
    const std::string name = attribute.first;
    std::string value;
    if (!FindXmlAttribute(element, name, value))
    {
      continue;
    }
    std::istringstream words(value);
    std::string word;
    int count = 0;
    bool finite = true;
    while (words >> word)
    {
      char* stop = nullptr;
      const double v = std::strtod(word.c_str(), &stop);
      finite = finite && stop == word.c_str() + word.size() && std::isfinite(v);
      ++count;
    }
    if (!finite || count != attribute.second)
    {
      Unreadable(path, "its " + name + " \"" + value + "\" is not " +
          std::to_string(attribute.second) + " finite numbers (VTK's reader would use the "
          "default instead)");
    }
  }
}

// A .vti whose uncompressed appended data was cut short: VTK 9.1's reader
// fills the missing values with zeros or garbage and reports nothing. Each
// array's block (a byte count of header_type, then the bytes; base64
// encoded as one stream with encoding="base64") must end within the file,
// before its closing </AppendedData> if it has one. (Compressed data is
// not looked at here: its reader fails on a cut block.)
void CheckAppendedData(const std::string& path)
{
  // The XML part comes first; the appended data follows the '_' after
  // <AppendedData ...>.
  const std::string head = FileHead(path, VtiXmlWindow);
  std::ifstream in(path, std::ios::binary);
  if (!in)
  {
    return;
  }
  const size_t appended = FindTag(head, "<AppendedData");
  const size_t fileTag = FindTag(head, "<VTKFile");
  if (appended == std::string::npos || fileTag == std::string::npos)
  {
    return;
  }
  const std::string vtkFile = head.substr(fileTag, head.find('>', fileTag) - fileTag);
  const size_t appendedEnd = head.find('>', appended);
  const std::string encoding = appendedEnd == std::string::npos
    ? std::string()
    : XmlAttribute(head.substr(appended, appendedEnd - appended), "encoding");
  const bool base64 = encoding == "base64";
  if ((encoding != "raw" && !base64) || !XmlAttribute(vtkFile, "compressor").empty())
  {
    return;
  }
  const size_t underscore = head.find('_', appendedEnd);
  if (underscore == std::string::npos)
  {
    return;
  }
  const unsigned long long dataStart = underscore + 1;
  const int headerSize = XmlAttribute(vtkFile, "header_type") == "UInt64" ? 8 : 4;
  const bool bigEndian = XmlAttribute(vtkFile, "byte_order") == "BigEndian";
  // The characters of an encoded header, and the bytes they decode to.
  const int headerChars = (headerSize + 2) / 3 * 4;
  in.clear();
  in.seekg(0, std::ios::end);
  unsigned long long fileSize = static_cast<unsigned long long>(in.tellg());
  // The data ends before the closing tag, when the file still has it.
  {
    const unsigned long long tailSize = std::min<unsigned long long>(fileSize, 4096);
    std::string tail(static_cast<size_t>(tailSize), '\0');
    in.seekg(static_cast<std::streamoff>(fileSize - tailSize));
    in.read(&tail[0], static_cast<std::streamsize>(tailSize));
    const size_t closing = tail.rfind("</AppendedData>");
    if (in.gcount() == static_cast<std::streamsize>(tailSize) && closing != std::string::npos &&
      fileSize - tailSize + closing >= dataStart)
    {
      fileSize = fileSize - tailSize + closing;
    }
    in.clear();
  }
  for (size_t at = FindTag(head, "<DataArray"); at != std::string::npos && at < appended;
       at = FindTag(head, "<DataArray", at + 1))
  {
    const std::string tag = head.substr(at, head.find('>', at) - at);
    const std::string offsetText = XmlAttribute(tag, "offset");
    if (XmlAttribute(tag, "format") != "appended" || offsetText.empty())
    {
      continue;
    }
    const unsigned long long offset = std::strtoull(offsetText.c_str(), nullptr, 10);
    const unsigned long long block = dataStart + offset;
    const int stored = base64 ? headerChars : headerSize;
    std::string header(static_cast<size_t>(stored), '\0');
    unsigned long long count = 0;
    bool complete = block + stored <= fileSize;
    if (complete)
    {
      in.seekg(static_cast<std::streamoff>(block));
      in.read(&header[0], stored);
      complete = in.gcount() == stored &&
        BlockByteCount(base64 ? Base64Prefix(header, headerSize) : header, headerSize,
          bigEndian, count) &&
        count <= fileSize;
      in.clear();
    }
    if (complete)
    {
      const unsigned long long size =
        base64 ? Base64BlockSize(headerSize, count) : headerSize + count;
      complete = block + size <= fileSize;
    }
    if (!complete)
    {
      Unreadable(path,
        "the appended data of array '" + XmlAttribute(tag, "Name") +
          "' ends past the end of the file (is the file complete?)");
    }
  }
}

// A compressed .vti array whose block header (header_type words: the
// number of blocks, the size of a block, the size of the last one, then
// each block's compressed size) gives no block, blocks of 0 bytes, or a
// last block larger than a block: VTK 9.1's reader dereferenced a null
// block (SIGSEGV) or divided by the block size (SIGFPE). Appended (raw or
// base64) and inline arrays, in the XML window of the file; an array of no
// tuples may have no block.
void CheckCompressedBlockHeaders(const std::string& path)
{
  const std::string head = FileHead(path, VtiXmlWindow);
  const size_t fileTag = FindTag(head, "<VTKFile");
  if (fileTag == std::string::npos)
  {
    return;
  }
  const std::string vtkFile = head.substr(fileTag, head.find('>', fileTag) - fileTag);
  if (XmlAttribute(vtkFile, "compressor").empty())
  {
    return;
  }
  const int headerSize = XmlAttribute(vtkFile, "header_type") == "UInt64" ? 8 : 4;
  const bool bigEndian = XmlAttribute(vtkFile, "byte_order") == "BigEndian";
  const size_t words = static_cast<size_t>(3 * headerSize);
  const size_t appended = FindTag(head, "<AppendedData");
  const size_t appendedEnd = appended == std::string::npos ? appended : head.find('>', appended);
  const bool base64 = appendedEnd != std::string::npos &&
    XmlAttribute(head.substr(appended, appendedEnd - appended), "encoding") == "base64";
  const size_t underscore =
    appendedEnd == std::string::npos ? std::string::npos : head.find('_', appendedEnd);
  std::ifstream in(path, std::ios::binary);
  for (size_t at = FindTag(head, "<DataArray"); at != std::string::npos && at < appended;
       at = FindTag(head, "<DataArray", at + 1))
  {
    const size_t close = head.find('>', at);
    if (close == std::string::npos)
    {
      return;
    }
    const std::string tag = head.substr(at, close - at);
    const std::string format = XmlAttribute(tag, "format");
    std::string header; // the first three words of the block header
    if (format == "binary")
    {
      header = Base64Prefix(head.substr(close + 1, 4 * words), words);
    }
    else if (format == "appended" && underscore != std::string::npos)
    {
      const unsigned long long offset =
        std::strtoull(XmlAttribute(tag, "offset").c_str(), nullptr, 10);
      const size_t stored = base64 ? (words + 2) / 3 * 4 : words;
      std::string raw(stored, '\0');
      in.clear();
      in.seekg(static_cast<std::streamoff>(underscore + 1 + offset));
      in.read(&raw[0], static_cast<std::streamsize>(stored));
      raw.resize(static_cast<size_t>(std::max<std::streamsize>(0, in.gcount())));
      header = base64 ? Base64Prefix(raw, words) : raw;
    }
    else
    {
      continue;
    }
    unsigned long long blocks = 0, blockSize = 0, lastSize = 0;
    if (!BlockByteCount(header, headerSize, bigEndian, blocks) ||
      !BlockByteCount(header.substr(static_cast<size_t>(headerSize)), headerSize, bigEndian,
        blockSize) ||
      !BlockByteCount(header.substr(static_cast<size_t>(2 * headerSize)), headerSize, bigEndian,
        lastSize))
    {
      continue; // cut short: the reader says so
    }
    if (XmlAttribute(tag, "NumberOfTuples") == "0" && blocks == 0)
    {
      continue;
    }
    if (blocks == 0 || blockSize == 0 || lastSize > blockSize)
    {
      Unreadable(path, "the compressed data of array '" + XmlAttribute(tag, "Name") +
          "' has a block header of " + std::to_string(blocks) + " blocks of " +
          std::to_string(blockSize) + " bytes, the last of " + std::to_string(lastSize) +
          ", which VTK's XML reader crashes on");
    }
  }
}

// A .vti whose uncompressed inline binary (base64) DataArray holds fewer
// characters than its header's byte count needs (cut short, the element
// closed again): VTK 9.1's reader reads on into the closing tag and fills
// the rest with garbage, without a word. The file is read through once,
// up to any <AppendedData> (raw bytes follow it).
void CheckInlineBinaryData(const std::string& path)
{
  // (Any spelling of the attribute: format='binary' or format = "binary"
  // passed a search for the text format="binary", as did a first binary
  // array past the first 64 KiB.)
  const std::string head = FileHead(path, VtiXmlWindow);
  const size_t fileTag = head.find("<VTKFile");
  if (fileTag == std::string::npos || head.find("binary") == std::string::npos)
  {
    return;
  }
  const std::string vtkFile = head.substr(fileTag, head.find('>', fileTag) - fileTag);
  if (!XmlAttribute(vtkFile, "compressor").empty())
  {
    return;
  }
  const int headerSize = XmlAttribute(vtkFile, "header_type") == "UInt64" ? 8 : 4;
  const bool bigEndian = XmlAttribute(vtkFile, "byte_order") == "BigEndian";
  const size_t headerChars = static_cast<size_t>((headerSize + 2) / 3 * 4);
  std::ifstream in(path, std::ios::binary);
  std::istreambuf_iterator<char> it(in), end;
  while (it != end)
  {
    if (*it++ != '<')
    {
      continue;
    }
    std::string tag;
    while (it != end && *it != '>')
    {
      tag.push_back(*it++);
    }
    if (it != end)
    {
      ++it;
    }
    if (tag.compare(0, 12, "AppendedData") == 0)
    {
      return;
    }
    if (tag.compare(0, 9, "DataArray") != 0 || XmlAttribute(tag, "format") != "binary" ||
      (!tag.empty() && tag.back() == '/'))
    {
      continue;
    }
    // The element's text: its characters (whitespace aside) and the first
    // ones, which hold the header.
    std::string start;
    unsigned long long chars = 0;
    for (; it != end && *it != '<'; ++it)
    {
      if (!std::isspace(static_cast<unsigned char>(*it)))
      {
        ++chars;
        if (start.size() < headerChars)
        {
          start.push_back(*it);
        }
      }
    }
    unsigned long long count = 0;
    const bool hasHeader =
      BlockByteCount(Base64Prefix(start, static_cast<size_t>(headerSize)), headerSize, bigEndian,
        count);
    const unsigned long long need =
      hasHeader ? Base64BlockSize(headerSize, count) : headerChars;
    if (!hasHeader || chars < need)
    {
      Unreadable(path,
        "the binary data of array '" + XmlAttribute(tag, "Name") + "' is " +
          std::to_string(chars) + " base64 characters, fewer than the " + std::to_string(need) +
          " its size needs (is the file complete?)");
    }
  }
}

}
