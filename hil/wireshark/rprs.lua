-- RPRS radio frames for Wireshark (docs/protocol.md section 3; docs/wireshark.md).
--
-- A capture from `rprs sim --pcap` puts each radio transmission on an interface of link type
-- USER0 (147); this dissector decodes it: Header 0F 0A 05, Destination, Source, Number,
-- Type, Length (ASCII digits), Content (commands name(args)), End 17 19. A frame that breaks
-- the format gets expert info (bad Header, a digit that is not one, a Length that does not
-- fit the bytes, a bad End) and stays in the capture. CAN frames on the same capture use
-- Wireshark's own SocketCAN dissector.
--
-- Display filters: rprs.src == 2, rprs.type == 4, rprs.cmd == "movex", rprs.dst == 7.

local rprs = Proto("rprs", "RPRS radio frame")

local type_names = {
    [0] = "seek help", [1] = "invitation", [2] = "instruction",
    [3] = "broadcast information", [4] = "failure", [5] = "boot", [6] = "join",
}

local f = rprs.fields
f.header = ProtoField.bytes("rprs.header", "Header")
f.dst = ProtoField.uint8("rprs.dst", "Destination", base.DEC)
f.src = ProtoField.uint8("rprs.src", "Source", base.DEC)
f.num = ProtoField.uint8("rprs.num", "Number", base.DEC)
f.type = ProtoField.uint8("rprs.type", "Type", base.DEC, type_names)
f.len = ProtoField.uint16("rprs.len", "Length", base.DEC)
f.content = ProtoField.string("rprs.content", "Content")
f.cmd = ProtoField.string("rprs.cmd", "Command")
f.args = ProtoField.string("rprs.args", "Arguments")
f.endmark = ProtoField.bytes("rprs.end", "End")

local e_header = ProtoExpert.new("rprs.header.bad", "No Header 0F 0A 05: garbage or a cut frame",
                                 expert.group.MALFORMED, expert.severity.ERROR)
local e_digit = ProtoExpert.new("rprs.digit.bad", "Not ASCII decimal digits",
                                expert.group.MALFORMED, expert.severity.ERROR)
local e_length = ProtoExpert.new("rprs.len.bad", "Length does not fit the frame's bytes",
                                 expert.group.MALFORMED, expert.severity.ERROR)
local e_end = ProtoExpert.new("rprs.end.bad", "End is not 17 19",
                              expert.group.MALFORMED, expert.severity.ERROR)
rprs.experts = { e_header, e_digit, e_length, e_end }

local function number(tvb, offset, width, tree, field)
    local range = tvb(offset, width)
    local text = range:string()
    if text:match("^%d+$") then
        local value = tonumber(text)
        tree:add(field, range, value)
        return value
    end
    tree:add(field, range, 0):add_proto_expert_info(e_digit)
    return nil
end

function rprs.dissector(tvb, pinfo, tree)
    local n = tvb:len()
    if n == 0 then return 0 end
    pinfo.cols.protocol = "RPRS"
    local t = tree:add(rprs, tvb(), "RPRS radio frame")
    if n < 14 or tvb(0, 3):bytes():tohex() ~= "0F0A05" then
        t:add_proto_expert_info(e_header)
        pinfo.cols.info = string.format("not a frame (%d bytes)", n)
        return n
    end
    t:add(f.header, tvb(0, 3))
    local dst = number(tvb, 3, 1, t, f.dst)
    local src = number(tvb, 4, 1, t, f.src)
    local num = number(tvb, 5, 2, t, f.num)
    local typ = number(tvb, 7, 1, t, f.type)
    local len = number(tvb, 8, 4, t, f.len)
    local info = string.format("%s -> %s #%s %s", src or "?", dst or "?", num or "?",
                               type_names[typ] or ("type " .. tostring(typ)))
    local clen = len
    if len == nil or 12 + len + 2 > n then
        t:add_proto_expert_info(e_length)
        clen = n - 12
    end
    local crange = clen > 0 and tvb(12, clen) or nil
    if crange then
        local ct = t:add(f.content, crange)
        local content = crange:string()
        local pos = 1
        while true do
            local s, e, name, args = content:find("(%a+)%(([^)]*)%)", pos)
            if not s then break end
            local item = ct:add(f.cmd, tvb(12 + s - 1, e - s + 1), name)
            item:add(f.args, tvb(12 + s - 1 + #name + 1, #args > 0 and #args or 0), args)
            info = info .. " " .. name .. "(" .. args .. ")"
            pos = e + 1
        end
    end
    if len ~= nil and 12 + len + 2 <= n then
        local erange = tvb(12 + len, 2)
        local item = t:add(f.endmark, erange)
        if erange:bytes():tohex() ~= "1719" then
            item:add_proto_expert_info(e_end)
        end
        if 12 + len + 2 < n then
            t:add_proto_expert_info(e_length, "bytes after End")
        end
    end
    pinfo.cols.info = info
    return n
end

local encaps = wtap_encaps or wtap
DissectorTable.get("wtap_encap"):add(encaps.USER0, rprs)
