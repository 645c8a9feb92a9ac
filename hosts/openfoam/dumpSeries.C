/*---------------------------------------------------------------------------*\
    vfe: void fraction of CFD cells from DEM particles
\*---------------------------------------------------------------------------*/

#include "dumpSeries.H"

#include <zlib.h>
#include <glob.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <sstream>
#include <stdexcept>

namespace
{

//- Line reader over zlib, which reads plain files as they are.
class lineReader
{
    gzFile f_;
    std::string file_;
    long line_ = 0;

public:
    explicit lineReader(const std::string& file)
    :
        f_(gzopen(file.c_str(), "rb")),
        file_(file)
    {
        if (!f_)
        {
            throw std::runtime_error
            (
                file + ": cannot open the dump (" + std::strerror(errno) + ")"
            );
        }
        gzbuffer(f_, 1 << 17);
    }
    ~lineReader() { gzclose(f_); }
    lineReader(const lineReader&) = delete;
    lineReader& operator=(const lineReader&) = delete;

    //- Next line without its newline; false at the end of the file.
    bool next(std::string& s)
    {
        s.clear();
        char buf[4096];
        while (gzgets(f_, buf, sizeof buf))
        {
            s += buf;
            if (!s.empty() && s.back() == '\n')
            {
                s.pop_back();
                ++line_;
                return true;
            }
        }
        int err = 0;
        gzerror(f_, &err);
        if (err != Z_OK && err != Z_STREAM_END)
        {
            fail("the file is damaged (" + std::string(gzerror(f_, &err)) + ")");
        }
        if (s.empty()) return false;
        ++line_;
        return true;
    }

    [[noreturn]] void fail(const std::string& what) const
    {
        std::ostringstream o;
        o << file_ << ":" << line_ << ": " << what;
        throw std::runtime_error(o.str());
    }

    //- The line after an "ITEM: <name>" line, which must come next.
    std::string expectItem(const std::string& name, std::string& itemLine)
    {
        if (!next(itemLine) || itemLine.compare(0, 6 + name.size(), "ITEM: " + name) != 0)
        {
            fail("expected 'ITEM: " + name + "'; is this a LIGGGHTS/LAMMPS text dump?");
        }
        std::string value;
        if (!next(value)) fail("the file ends after 'ITEM: " + name + "'");
        return value;
    }
};

long parseLong(lineReader& in, const std::string& s, const char* what)
{
    char* end = nullptr;
    errno = 0;
    const long v = std::strtol(s.c_str(), &end, 10);
    while (end && (*end == ' ' || *end == '\t' || *end == '\r')) ++end;
    if (errno || end == s.c_str() || *end != '\0' || v < 0)
    {
        in.fail(std::string("bad ") + what + " '" + s + "'");
    }
    return v;
}

struct header
{
    long timestep;
    std::int64_t n;
    std::vector<std::string> columns;
};

//- Reads one snapshot header; false at the end of the file.
bool readHeader(lineReader& in, header& h)
{
    std::string item, value;
    if (!in.next(item)) return false;
    if (item.compare(0, 14, "ITEM: TIMESTEP") != 0)
    {
        in.fail("expected 'ITEM: TIMESTEP'; is this a LIGGGHTS/LAMMPS text dump?");
    }
    if (!in.next(value)) in.fail("the file ends after 'ITEM: TIMESTEP'");
    h.timestep = parseLong(in, value, "timestep");
    h.n = parseLong(in, in.expectItem("NUMBER OF ATOMS", item), "atom count");
    in.expectItem("BOX BOUNDS", item);
    for (int k = 0; k < 2; ++k)
    {
        if (!in.next(value)) in.fail("the file ends inside the box bounds");
    }
    if (!in.next(item) || item.compare(0, 11, "ITEM: ATOMS") != 0)
    {
        in.fail("expected 'ITEM: ATOMS id type x y z ...'");
    }
    std::istringstream cols(item.substr(11));
    h.columns.clear();
    for (std::string c; cols >> c;) h.columns.push_back(c);
    return true;
}

} // namespace


int Foam::vfe::dumpFrame::column(const std::string& name) const
{
    const auto it = std::find(columns.begin(), columns.end(), name);
    return it == columns.end() ? -1 : int(it - columns.begin());
}


Foam::vfe::dumpSeries::dumpSeries(const std::string& pattern)
{
    glob_t g;
    const int rc = ::glob(pattern.c_str(), 0, nullptr, &g);
    std::vector<std::string> files;
    if (rc == 0)
    {
        for (std::size_t i = 0; i < g.gl_pathc; ++i) files.push_back(g.gl_pathv[i]);
    }
    globfree(&g);
    if (files.empty())
    {
        throw std::runtime_error
        (
            "no dump file matches '" + pattern + "'; set 'dumps' to a glob of "
            "LIGGGHTS/LAMMPS dumps (relative paths are relative to the case)"
        );
    }
    std::string skip;
    for (const std::string& f : files)
    {
        lineReader in(f);
        header h{};
        for (int k = 0; readHeader(in, h); ++k)
        {
            entries_.push_back(entry{f, k, h.timestep});
            for (std::int64_t r = 0; r < h.n; ++r)
            {
                if (!in.next(skip)) in.fail("the file ends inside the atom list");
            }
        }
    }
    std::stable_sort
    (
        entries_.begin(), entries_.end(),
        [](const entry& a, const entry& b) { return a.timestep < b.timestep; }
    );
}


long Foam::vfe::dumpSeries::frameAt(const double t, const double dt) const
{
    long best = -1;
    for (std::size_t i = 0; i < entries_.size(); ++i)
    {
        if (double(entries_[i].timestep)*dt <= t + 1e-6*dt) best = long(i);
    }
    return best;
}


Foam::vfe::dumpFrame Foam::vfe::dumpSeries::read(const std::size_t i) const
{
    const entry& e = entries_.at(i);
    lineReader in(e.file);
    header h{};
    std::string line;
    for (int k = 0; k <= e.ordinal; ++k)
    {
        if (!readHeader(in, h)) in.fail("the snapshot is gone; was the file changed?");
        if (k == e.ordinal) break;
        for (std::int64_t r = 0; r < h.n; ++r) in.next(line);
    }
    dumpFrame f;
    f.timestep = h.timestep;
    f.n = h.n;
    f.columns = h.columns;
    const std::size_t nc = f.columns.size();
    f.table.resize(std::size_t(h.n)*nc);
    for (std::int64_t r = 0; r < h.n; ++r)
    {
        if (!in.next(line)) in.fail("the file ends inside the atom list");
        const char* p = line.c_str();
        for (std::size_t c = 0; c < nc; ++c)
        {
            char* end = nullptr;
            const double v = std::strtod(p, &end);
            if (end == p) in.fail("expected " + std::to_string(nc) + " numbers per atom");
            f.table[std::size_t(r)*nc + c] = v;
            p = end;
        }
    }
    return f;
}
